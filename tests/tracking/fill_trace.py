"""Which fill tried which run of a marker's gap, and what each placed (not a test; run it).

    python -m tests.tracking.fill_trace 311 RTOE 28-32 --rig=lowcost
    python -m tests.tracking.fill_trace 306 LTHI 37-47 --rig=lowcost
    python -m tests.tracking.fill_trace 311 --dishonest --rig=lowcost

Issue 27's open gaps (:mod:`tests.tracking.coverage_gaps` lists them) are explained field
by field here: the trial of :mod:`tests.tracking.few_cameras_acceptance` is tracked with
every fill of :mod:`kisscal.tracking.fill_passes` (the first pass and the ends, the second pass,
the last pass) wrapped so that each call on the named marker's track over the fields
asked for prints its pass, the gap and run it was given, and the fields it placed
(``x``); a fill the runner does not call there (its reach, :class:`Fill`) is not
printed. Then each fill of that marker kept in those fields, its expected error against
its RMS and largest error from truth.
"""

from __future__ import annotations

import dataclasses
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numpy as np

from kisscal.tracking import STATUS_NAMES, gaps
from kisscal.tracking.fill_table import Fill
from tests.tracking.few_cameras_acceptance import RIGS, rig_trial, track_trial


def _traced(fills: tuple[Fill, ...], tag: str, show: Callable) -> tuple[Fill, ...]:
    """``fills``, each calling ``show(tag, fill, gap, a, b, placed)`` after it ran."""

    def wrap(fill: Fill) -> Fill:
        def run(gap, a: int, b: int, params):
            placed = fill.fill(gap, a, b, params)
            show(tag, fill, gap, a, b, placed)
            return placed

        return dataclasses.replace(fill, fill=run)

    return tuple(wrap(f) for f in fills)


@contextmanager
def tracing(show: Callable) -> Iterator[None]:
    """Every pass's fills (:mod:`kisscal.tracking.fill_passes`, as
    :func:`kisscal.tracking.gaps.fill_gaps_named` reads them) traced by ``show`` (see
    :func:`_traced`) while in the context."""
    saved = gaps.FILLS, gaps.SECOND_PASS, gaps.LAST_PASS, gaps.TRUSTED_PASS
    gaps.FILLS = _traced(gaps.FILLS, "first/end", show)
    gaps.SECOND_PASS = _traced(gaps.SECOND_PASS, "second", show)
    gaps.LAST_PASS = _traced(gaps.LAST_PASS, "last", show)
    gaps.TRUSTED_PASS = _traced(gaps.TRUSTED_PASS, "trusted", show)
    try:
        yield
    finally:
        gaps.FILLS, gaps.SECOND_PASS, gaps.LAST_PASS, gaps.TRUSTED_PASS = saved


def trace(trial, name: str, lo: int, hi: int) -> list[str]:
    """The fills tried on marker ``name``'s track over fields [lo, hi) of ``trial``, and
    the fills kept there against truth (see module)."""
    lines: list[tuple[int, str]] = []

    def show(tag, fill, gap, a, b, placed) -> None:
        if a < hi and b > lo:
            mask = "".join("x" if p else "." for p in placed)
            lines.append(
                (
                    gap.t,
                    f"{tag:9s} gap {gap.lo}-{gap.hi} end {gap.end:+d} run {a}-{b} "
                    f"{fill.name:22s} {mask}",
                )
            )

    with tracing(show):
        res = track_trial(trial)
    track = [t for t, label in enumerate(res.labels) if label == name]
    out = [f"{name}: track {track}"] + [s for t, s in lines if t in track]
    j = trial.names.index(name)
    tr = res.tracks
    for g in res.fills:
        if g.track not in track or g.first_field >= hi or g.first_field + g.n_fields <= lo:
            continue
        f = g.first_field + np.arange(g.n_fields)
        rows = np.flatnonzero((tr.track == g.track) & np.isin(tr.field, f))
        err = np.linalg.norm(tr.xyz_mm[rows] - trial.truth[tr.field[rows], j], axis=1)
        out.append(
            f"kept {f[0]}-{f[-1] + 1} {STATUS_NAMES[g.status]} expected "
            f"{g.expected_error_mm:.2f} mm, true RMS {np.sqrt(np.mean(err**2)):.2f} max "
            f"{err.max():.2f}, donors {[res.labels[d] for d in g.donors]}"
        )
    return out


def dishonest(trial) -> list[str]:
    """Every fill of ``trial`` with a sample whose true error is over twice the fill's
    expected error (the acceptance table's count): marker, fields, method, expected
    error, true RMS and largest error, donors."""
    res = track_trial(trial)
    tr, out = res.tracks, []
    for g in res.fills:
        name = res.labels[g.track]
        if name not in trial.names:
            continue
        f = g.first_field + np.arange(g.n_fields)
        rows = np.flatnonzero((tr.track == g.track) & np.isin(tr.field, f))
        err = np.linalg.norm(
            tr.xyz_mm[rows] - trial.truth[tr.field[rows], trial.names.index(name)], axis=1
        )
        n = int(np.sum(err > 2.0 * g.expected_error_mm))
        if n:
            out.append(
                f"{name} {f[0]}-{f[-1] + 1} {STATUS_NAMES[g.status]} ({n} over) expected "
                f"{g.expected_error_mm:.2f} mm, true RMS {np.sqrt(np.mean(err**2)):.2f} max "
                f"{err.max():.2f}, donors {[res.labels[d] for d in g.donors]}"
            )
    return out


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("-")]
    only = next((a.split("=", 1)[1] for a in sys.argv if a.startswith("--rig=")), "lowcost")
    rig = next((v for k, v in RIGS.items() if k.startswith(only)), None)
    if not args or {"-h", "--help"} & set(sys.argv) or rig is None:
        sys.exit(f"{__doc__}\n--rig= takes the start of one of: {', '.join(RIGS)}")
    preset, cams = rig
    if "--dishonest" in sys.argv:
        print("\n".join(dishonest(rig_trial(preset, int(args[0]), cams))))
    else:
        seed, marker, (first, stop) = int(args[0]), args[1], map(int, args[2].split("-"))
        print("\n".join(trace(rig_trial(preset, seed, cams), marker, first, stop)))
