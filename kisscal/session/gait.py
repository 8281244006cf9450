"""Gait outputs of a trial: ``events.csv``, ``spatiotemporal.csv``, ``gait.json``, a figure.

Written when the trial's labelled trajectories carry the marker set's feet (a heel and a
toe marker on each side) and pelvis, labelled with certainty; trials without them (a
stick, a thrown marker, a static trial) get none, and no error. Events found on
uncertain labels (a heel that may be the other foot's) would be wrong without saying
so: such a trial gets no gait outputs either, and the log says why.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.errors import KisscalError
from kisscal.gait import (
    GaitEvents,
    GaitParams,
    detect_events,
    gait_markers,
    spatiotemporal_parameters,
)
from kisscal.gait.figures import gait_cycle_figure
from kisscal.gait.spatiotemporal import outside_walking
from kisscal.io.files import write_json, write_table
from kisscal.io.store import SessionStore
from kisscal.markersets import MarkerSet
from kisscal.session.inputs import figure
from kisscal.tracking import Trajectories

#: Columns of ``spatiotemporal.csv``.
SPATIOTEMPORAL_COLUMNS = ("parameter", "side", "mean", "sd", "unit", "n_strides")
#: Columns of ``events.csv``.
EVENT_COLUMNS = ("side", "event", "field", "time_s")


def _columns(rows: list[dict[str, Any]], names: tuple[str, ...]) -> dict[str, list]:
    return {c: [r[c] for r in rows] for c in names}


def clear_gait_outputs(root: Path, trial: str) -> None:
    """Remove a trial's gait outputs of an earlier run."""
    store = SessionStore(root)
    files = store.trial(trial)
    for path in (
        files.events,
        files.spatiotemporal,
        files.gait,
        store.figure_path(f"gait_{trial}"),
    ):
        path.unlink(missing_ok=True)


def gait_outputs(
    root: Path,
    trial: str,
    result: Trajectories,
    marker_set: MarkerSet | None,
    rate_hz: float,
    params: GaitParams,
    echo: Callable[[str], object],
) -> GaitEvents | None:
    """Detect events, compute spatiotemporal parameters and write them; None (nothing
    written) when the trajectories lack the set's feet or pelvis, or their labels are
    uncertain."""

    clear_gait_outputs(root, trial)  # an earlier run's would be stale
    if marker_set is None or not result.labelling.fits_marker_set:
        return None
    dense = result.tracks.positions()
    by_label = {label: dense[t] for t, label in enumerate(result.labels)}
    try:
        markers = gait_markers(by_label, rate_hz, marker_set, params)
    except KisscalError as err:
        feet = {n for side in ("left", "right") for n in marker_set.foot(side).values()}
        if set(by_label) & (feet | set(marker_set.pelvis)):  # a gait trial short of markers
            echo(f"  gait {trial}: no events, {str(err).removeprefix('gait: ')}")
        return None
    uncertain = sorted(
        set(result.labelling.flagged) & set(",".join(markers.names.values()).split(","))
    )
    if uncertain:
        echo(f"  gait {trial}: no events, the labels of {', '.join(uncertain)} are uncertain")
        return None
    events = detect_events(markers, params)
    parameters = spatiotemporal_parameters(events, markers)
    for note in events.warnings:  # why events or full strides are missing
        echo(f"  gait {trial}: {note}")
    implausible = outside_walking(parameters, params)
    if implausible:  # the cameras measured distances; times are fields / rate_hz
        echo(
            f"  warning: {trial}: {' and '.join(implausible)}: is [session] rate_hz = "
            f"{rate_hz:g} right? cadence, speed and walk ratio scale with it"
        )
    files = SessionStore(root).trial(trial)
    write_table(files.events, _columns(events.rows(), EVENT_COLUMNS))
    write_table(files.spatiotemporal, _columns(parameters.rows(), SPATIOTEMPORAL_COLUMNS))
    counts = {
        f"{side}_{event}": int(np.sum((events.side == side) & (events.event == event)))
        for side in ("left", "right")
        for event in ("foot_strike", "foot_off")
    }
    doc = {
        "events": counts,
        "markers": markers.names,
        "spatiotemporal": parameters.summary(),
        "warnings": list(events.warnings),
    }
    write_json(files.gait, doc)
    title = f"trial {trial}: gait cycle (heel and toe height, events)"
    figure(root, f"gait_{trial}", gait_cycle_figure, markers, events, None, title, params)
    return events
