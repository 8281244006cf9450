"""Gait events on real trials against the events their labs marked (run it):

    python -m tests.gait.real_events

For every trial of fixtures/real/gait/ (see its README: source, licence, system), the
mean and worst absolute error of kisscal's foot strikes and foot offs against the marked
ones, next to Zeni et al. (2008)'s coordinate rule on the same markers (heel furthest
ahead of the pelvis at foot strike, toe furthest behind at foot off). A marked event
with no detection within 150 ms counts as missed (unless it lies within 0.4 s of the
trial's start or 0.3 s of its end, where the stride is cut); a detection with no
marked event near it is not scored (labs mark only some events of a trial).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np

from kisscal._shared import true_runs
from kisscal.gait import GaitMarkers, detect_events
from kisscal.gait.events import foot_direction, pelvis_centre
from kisscal.gait.table import EVENTS, SIDES, GaitEvents
from tests.gait import _real

#: A detection further than this from a marked event does not match it (the marked
#: event is missed).
MATCH_S = 0.15
#: Marked events this close to the start or the end of a trial (s) belong to strides
#: cut by it: not finding them is not a miss.
EDGE_S = (0.4, 0.3)
#: Zeni's rule: an extremum of a foot's position relative to the pelvis counts if it
#: stands out by this fraction of the position's range ...
PROMINENCE = 0.3
#: ... and two extrema of one foot are at least this far apart (s): a stride is longer
#: than 0.7 s even when running.
MIN_STEP_S = 0.5


def coordinate_events(markers: GaitMarkers) -> GaitEvents:
    """Zeni et al. (2008)'s coordinate rule alone: foot strike when the heel is furthest
    ahead of the pelvis, foot off when the toe is furthest behind it.

    Positions are taken relative to the centre of the pelvis markers along the feet's
    direction (:func:`~kisscal.gait.events.foot_direction`); an extremum counts if it
    stands out by :data:`PROMINENCE` of the signal's range and is not cut by an end of
    the trial or a gap. Times are sub-field (parabola through the extreme sample and its
    neighbours).

    References
    ----------
    Zeni, Richards & Higginson 2008.
    """
    direction = foot_direction(markers)
    centre = pelvis_centre(markers)
    times: dict[tuple[str, str], list[float]] = {}
    for side in SIDES:
        for event, track, sign in (
            ("foot_strike", markers.heel[side], 1.0),
            ("foot_off", markers.toe[side], -1.0),
        ):
            along = np.sum((track - centre)[:, :2] * direction, axis=1)
            times[(side, event)] = list(_peaks(sign * along, markers.rate_hz))
    return GaitEvents.from_times(times, markers.rate_hz)


def _peaks(y: np.ndarray, rate: float) -> np.ndarray:
    """Sub-sample times of the clear maxima of ``y``, run of valid samples by run."""
    from scipy.signal import find_peaks

    valid = np.isfinite(y)
    if valid.sum() < 3:
        return np.array([])
    lo, hi = np.percentile(y[valid], [5, 95])
    distance = max(1, round(MIN_STEP_S * rate))
    t = np.arange(len(y)) / rate
    out = []
    for a, b in zip(*true_runs(valid), strict=True):
        if b - a < 3:
            continue
        for i in find_peaks(y[a:b], prominence=PROMINENCE * (hi - lo), distance=distance)[0]:
            out.append(peak_time(t, y, a + int(i)))
    return np.asarray([x for x in out if np.isfinite(x)], dtype=float)


def peak_time(t: np.ndarray, y: np.ndarray, i: int) -> float:
    """Sub-sample time of the maximum at sample ``i``: vertex of the parabola through i-1..i+1."""
    if i <= 0 or i >= len(y) - 1 or not np.all(np.isfinite(y[i - 1 : i + 2])):
        return float("nan")
    a, b, c = y[i - 1 : i + 2]
    den = a - 2 * b + c
    shift = 0.0 if den >= 0 else 0.5 * (a - c) / den
    return float(t[i] + shift * (t[i + 1] - t[i]))


@dataclass
class Errors:
    """Signed errors (s) per event kind and the number of marked events missed."""

    errors: dict[str, list[float]] = field(default_factory=lambda: {e: [] for e in EVENTS})
    missed: dict[str, int] = field(default_factory=lambda: dict.fromkeys(EVENTS, 0))

    def add(self, other: Errors) -> None:
        for e in EVENTS:
            self.errors[e] += other.errors[e]
            self.missed[e] += other.missed[e]

    def mean_ms(self, event: str) -> float:
        e = np.abs(self.errors[event])
        return 1000 * float(e.mean()) if len(e) else float("nan")

    def worst_ms(self, event: str) -> float:
        e = np.abs(self.errors[event])
        return 1000 * float(e.max()) if len(e) else float("nan")


def score(
    found: GaitEvents, marked: dict[tuple[str, str], np.ndarray], duration_s: float = np.inf
) -> Errors:
    """Nearest detection of the same side and kind for every marked event; one not
    found counts as missed unless its stride is cut by an end of the trial (within
    ``EDGE_S`` of it: kisscal only reports events of strides seen whole)."""
    out = Errors()
    for side in SIDES:
        for event in EVENTS:
            d = found.times(side, event)
            for t in marked.get((side, event), []):
                k = int(np.argmin(np.abs(d - t))) if len(d) else -1
                if k >= 0 and abs(d[k] - t) <= MATCH_S:
                    out.errors[event].append(float(d[k] - t))
                elif EDGE_S[0] <= t <= duration_s - EDGE_S[1]:
                    out.missed[event] += 1
    return out


def _cells(err: Errors) -> str:
    return "  ".join(
        f"{err.mean_ms(e):5.1f} {err.worst_ms(e):5.1f} {err.missed[e]:2d}" for e in EVENTS
    )


def table(
    group: str = "EVENT", trials: tuple[_real.RealTrial, ...] = _real.TRIALS
) -> tuple[list[str], Errors, Errors]:
    """Per-trial and pooled errors against the events of ``group`` (the lab's EVENT
    group, or ``_real.PLATE_GROUP``: the force plates' contacts); a held-out trial whose
    file is not in the cache is left out."""
    head = "mean worst miss"
    lines = [
        f"{'trial':<24} {'Hz':>4} {'n':>3}  {'kisscal FS':^17}  {'kisscal FO':^17}"
        f"  {'Zeni FS':^17}  {'Zeni FO':^17}",
        f"{'':<24} {'':>4} {'':>3}  {head:^17}  {head:^17}  {head:^17}  {head:^17}",
    ]
    ours_all, zeni_all = Errors(), Errors()
    ours_heel, zeni_heel = Errors(), Errors()  # trials whose feet carry a heel marker
    ours_ankle, zeni_ankle = Errors(), Errors()  # the others (a heel stand-in)
    for trial in trials:
        if (group == _real.PLATE_GROUP and not trial.plates) or not trial.path.is_file():
            continue
        gm, marked = _real.load(trial, group)
        if not marked:
            continue
        duration = gm.n_fields / gm.rate_hz
        ours = score(detect_events(gm), marked, duration)
        zeni = score(coordinate_events(gm), marked, duration)
        ours_all.add(ours)
        zeni_all.add(zeni)
        (ours_ankle if trial.ankle else ours_heel).add(ours)
        (zeni_ankle if trial.ankle else zeni_heel).add(zeni)
        n = sum(len(v) for v in marked.values())
        lines.append(f"{trial.name:<24} {gm.rate_hz:4.0f} {n:3d}  {_cells(ours)}  {_cells(zeni)}")
    for name, ours, zeni in (
        ("all", ours_all, zeni_all),
        ("with a heel marker", ours_heel, zeni_heel),
        ("without (ankle)", ours_ankle, zeni_ankle),
    ):
        n = sum(len(v) for v in ours.errors.values()) + sum(ours.missed.values())
        lines.append(f"{name:<24} {'':>4} {n:3d}  {_cells(ours)}  {_cells(zeni)}")
    lines.append("errors in ms (mean and worst absolute); miss = marked events not found")
    return lines, ours_all, zeni_all


def main(argv: list[str]) -> None:
    """``python -m tests.gait.real_events [held-out|zoo|all]``: the regression set
    (default), the held-out files (their plates' contacts; ``$KISSCAL_C3D_CACHE``), the
    biomechZoo Nexus trials, or the first two pooled."""
    which = argv[1] if len(argv) > 1 else "regression"
    trials = {"regression": _real.TRIALS, "held-out": _real.HELD_OUT, "zoo": _real.ZOO}
    trials["all"] = _real.TRIALS + _real.HELD_OUT
    print(f"{which}: against the events marked in the files:")
    print("\n".join(table("EVENT", trials[which])[0]))
    print(f"\n{which}: against the force plates' contacts (20 N; the foot over the plate):")
    print("\n".join(table(_real.PLATE_GROUP, trials[which])[0]))
    print()
    for trial in trials[which]:
        note = f"; {trial.note}" if trial.note else ""
        print(f"{trial.name}: {trial.system}; events: {trial.events_from}{note}")


if __name__ == "__main__":
    main(sys.argv)
