"""The session's marker set for the track stage: ``[markers]`` resolved, the static trial.

:func:`marker_spec` turns ``[markers]`` into what tracking needs: the shipped set chosen
by ``set`` (restricted to ``names``, with the session's ``segments``), the names and
template given by hand, or both. With ``static``, the static trial is labelled once from
the set and the subject's own median positions in it become the template of every other
trial (:func:`static_template`), cached under the static trial's outputs.
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kisscal.errors import EstimationFailed, InputError, KisscalError
from kisscal.io.config import SessionConfig
from kisscal.markersets import MarkerSet, available_marker_sets, marker_set
from kisscal.tracking import Trajectories
from kisscal.tracking.rigid import kabsch

#: A static trial's markers may wander this far (mm, 5th to 95th percentile) at most.
STATIC_MAX_MOVE_MM = 100.0


@dataclass(frozen=True)
class MarkerSpec:
    """What labelling and gait analysis use of ``[markers]``.

    Attributes
    ----------
    names : tuple of str or None
        Marker names (None: no marker set, tracks are named M1, M2, ...).
    template_mm : (n, 3) array or None
        A template in any frame (``template_mm`` given by hand), or the static trial's.
    template_upright : bool
        The template is in the lab frame, Z up (a static trial's positions).
    segments : tuple of (str, str)
    marker_set : MarkerSet or None
        The shipped set: labels through it (``set``), or, found by the names alone, its
        gait roles (heel, toe, pelvis) and nothing else.
    label_with_set : bool
        Whether labelling goes through the set (``set`` given).
    """

    names: tuple[str, ...] | None = None
    template_mm: NDArray[np.float64] | None = None
    template_upright: bool = False
    segments: tuple[tuple[str, str], ...] = ()
    marker_set: MarkerSet | None = None
    label_with_set: bool = False


def _set_of_names(names: tuple[str, ...]) -> MarkerSet | None:
    """A shipped set that knows every name (its own or an alias), for gait roles."""
    for name in available_marker_sets():
        try:
            return marker_set(name, names)
        except KisscalError:
            continue
    return None


def marker_spec(config: SessionConfig) -> MarkerSpec:
    """``[markers]`` resolved (the static trial's template not yet included)."""
    m = config.markers
    if m is None:
        return MarkerSpec()
    template = None if m.template_mm is None else np.asarray(m.template_mm, dtype=float)
    if m.set is None:
        return MarkerSpec(m.names, template, False, m.segments, _set_of_names(m.names))
    chosen = marker_set(m.set, m.names or None)
    if m.segments:
        chosen = dataclasses.replace(chosen, segments=tuple(m.segments))
    if template is not None and len(template) != len(chosen):
        raise InputError(
            f"{config.path}: markers.template_mm has {len(template)} positions for the "
            f"{len(chosen)} markers of set {m.set!r}; give names in the template's order"
        )
    return MarkerSpec(chosen.names, template, False, chosen.segments, chosen, True)


def subject_template(result: Trajectories, spec: MarkerSpec, trial: str) -> dict:
    """The subject's template from a labelled static trial: each name's median position.

    Names the static trial does not show take the set's template (scaled to the subject,
    rigidly placed on the names it shows).

    Raises
    ------
    KisscalError
        The trial does not fit the set, its labels are uncertain, or the subject moves.
    """
    lab = result.labelling
    dense = result.tracks.positions()
    _check_still(dense, result.labels, trial)
    if not lab.fits_marker_set:
        raise EstimationFailed(f"static trial {trial!r}: its markers do not fit the marker set")
    if lab.flagged:
        raise EstimationFailed(
            f"static trial {trial!r}: labels {', '.join(lab.flagged)} are uncertain "
            "(left and right not told apart); check the static trial"
        )
    names = spec.names or ()
    row = {label: t for t, label in enumerate(result.labels)}
    pos = np.full((len(names), 3), np.nan)
    for i, name in enumerate(names):
        if name in row:
            track = dense[row[name]]
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                pos[i] = np.nanmedian(track, axis=0)
    seen = np.isfinite(pos[:, 0])
    if seen.sum() < 3:
        raise EstimationFailed(f"static trial {trial!r}: fewer than three markers labelled")
    height = lab.height_mm
    if spec.marker_set is not None and not seen.all():
        generic = spec.marker_set.scaled(height if np.isfinite(height) else 1750.0).template_mm
        r, t = kabsch(generic[seen], pos[seen])
        pos[~seen] = generic[~seen] @ r.T + t
    return {
        "trial": trial,
        "names": list(names),
        "template_mm": pos.round(2).tolist(),
        "seen": [bool(s) for s in seen],
        "height_mm": None if not np.isfinite(height) else float(height),
    }


def _check_still(dense: NDArray, labels: tuple[str, ...], trial: str) -> None:
    """The subject stands still: the median trajectory stays within
    :data:`STATIC_MAX_MOVE_MM` (5th to 95th percentile of its positions)."""
    spreads = []
    for track, label in zip(dense, labels, strict=True):
        seen = track[np.isfinite(track[:, 0])]
        if len(seen) >= 2:
            span = np.percentile(seen, 95, axis=0) - np.percentile(seen, 5, axis=0)
            spreads.append((float(np.linalg.norm(span)), label))
    if not spreads:
        return
    spread, label = sorted(spreads)[len(spreads) // 2]
    if spread > STATIC_MAX_MOVE_MM:
        raise EstimationFailed(
            f"static trial {trial!r}: the subject moves (its median marker, {label}, "
            f"travels {spread:.0f} mm; at most {STATIC_MAX_MOVE_MM:.0f} mm standing still)"
        )


def static_inputs(points_path: Path, spec: MarkerSpec, tracking: object) -> tuple:
    """What the static template is made from: the static trial's points, the set, the
    parameters (the parts of its cache key)."""
    ms = spec.marker_set
    return (
        "static",
        points_path,
        spec.names,
        spec.segments,
        None if ms is None else (ms.name, ms.template_mm),
        spec.template_mm,
        tracking,
    )
