"""Spatiotemporal gait parameters per side from gait events and heel trajectories.

Definitions (per side X, the conventions of clinical gait reports, e.g. Vicon Nexus):

* stride: from a foot strike of X to the next one (no foot strike of X missed between);
  stride time (s), cadence = 120 / stride time (steps/min), stride length = horizontal
  distance between the heel marker's positions at the two strikes (m; on a treadmill,
  positions on the belt), walking speed = stride length / stride time (m/s);
* stance = (foot off of X - foot strike of X) / stride time (% of the cycle), swing =
  100 - stance, double support = both feet on the floor: from the strike of X to the
  other foot's off, plus from the other foot's strike to the off of X (% of the cycle);
* step (at each foot strike of X, between the other foot's strikes before and after):
  step time = time since the other foot's strike (s); step length = the heel of X ahead
  of the other heel along the line joining the other heel's two strike positions (m);
  step width = distance of the heel of X from that line (m).

Each parameter is summarised per side as mean, SD (n - 1) and the number of strides.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.gait.events import ground_velocity
from kisscal.gait.markers import GaitMarkers
from kisscal.gait.params import GaitParams
from kisscal.gait.table import SIDES, GaitEvents

#: Parameter -> unit, in the order of the table.
UNITS = {
    "cadence": "steps/min",
    "walking_speed": "m/s",
    "stride_time": "s",
    "step_time": "s",
    "stride_length": "m",
    "step_length": "m",
    "step_width": "m",
    "stance": "%",
    "swing": "%",
    "double_support": "%",
}
_OTHER = {"left": "right", "right": "left"}


@dataclass(frozen=True, eq=False)
class Spatiotemporal:
    """Per-stride values of every parameter, per side.

    Attributes
    ----------
    values : dict
        ``(parameter, side)`` -> 1-D array, one value per stride (or step) of that side.
    """

    values: dict[tuple[str, str], NDArray[np.float64]]

    def mean(self, parameter: str, side: str) -> float:
        v = self.values[(parameter, side)]
        return float(np.mean(v)) if len(v) else float("nan")

    def rows(self) -> list[dict[str, object]]:
        """The ``spatiotemporal.csv`` rows: parameter, side, mean, sd, unit, n_strides."""
        rows = []
        for parameter, unit in UNITS.items():
            for side in SIDES:
                v = self.values[(parameter, side)]
                sd = float(np.std(v, ddof=1)) if len(v) > 1 else float("nan")
                mean = float(np.mean(v)) if len(v) else float("nan")
                rows.append(
                    {
                        "parameter": parameter,
                        "side": side,
                        "mean": mean,
                        "sd": sd,
                        "unit": unit,
                        "n_strides": len(v),
                    }
                )
        return rows

    def summary(self) -> dict[str, dict[str, object]]:
        """For ``summary.json``: parameter -> {"unit", "left": {mean, sd, n}, "right": ...}."""
        out: dict[str, dict[str, object]] = {}
        for row in self.rows():
            entry = out.setdefault(str(row["parameter"]), {"unit": row["unit"]})
            entry[str(row["side"])] = {
                "mean": _none_if_nan(row["mean"]),
                "sd": _none_if_nan(row["sd"]),
                "n": row["n_strides"],
            }
        return out


def outside_walking(st: Spatiotemporal, params: GaitParams) -> list[str]:
    """The mean cadence, walking speed and walk ratio (step length / cadence, Sekiya &
    Nagasaki 1998) of a trial that no one walks at (both sides' strides together), as
    ``"cadence 250 steps/min"``; empty when all three are plausible.

    Examples
    --------
    >>> st = Spatiotemporal({("cadence", "left"): np.array([250.0]),
    ...     ("cadence", "right"): np.array([260.0]), ("walking_speed", "left"): np.array([1.2]),
    ...     ("walking_speed", "right"): np.array([])})
    >>> outside_walking(st, GaitParams())
    ['cadence 255 steps/min (human: 30-200)']
    """
    means = {p: _mean_of_sides(st, p) for p in ("cadence", "walking_speed", "step_length")}
    # step lengths are distances, the cadence a rate: their ratio scales with 1 / rate_hz
    means["walk_ratio"] = means.pop("step_length") / means["cadence"]
    found = []
    for parameter, (lo, hi) in (
        ("cadence", params.human_cadence),
        ("walking_speed", params.human_speed),
        ("walk_ratio", params.human_walk_ratio),
    ):
        mean = means[parameter]
        if np.isfinite(mean) and not lo <= mean <= hi:
            name = parameter.replace("_", " ")
            unit = UNITS.get(parameter, "m/(steps/min)")
            found.append(f"{name} {mean:.3g} {unit} (human: {lo:g}-{hi:g})")
    return found


def _mean_of_sides(st: Spatiotemporal, parameter: str) -> float:
    """Mean of one parameter over both sides' strides (NaN without any)."""
    values = np.concatenate([st.values.get((parameter, side), np.empty(0)) for side in SIDES])
    return float(np.mean(values)) if len(values) else float("nan")


def _none_if_nan(x: object) -> object:
    return None if isinstance(x, float) and not np.isfinite(x) else x


def _at(track: NDArray[np.float64], rate_hz: float, times_s: NDArray) -> NDArray[np.float64]:
    """Positions (k, 3) of ``track`` at ``times_s`` by linear interpolation (NaN in gaps)."""
    x = np.asarray(times_s, dtype=float) * rate_hz
    i = np.clip(np.floor(x).astype(int), 0, len(track) - 2)
    f = (x - i)[:, None]
    out = (1 - f) * track[i] + f * track[i + 1]
    out[(x < 0) | (x > len(track) - 1)] = np.nan
    return out


def spatiotemporal_parameters(events: GaitEvents, markers: GaitMarkers) -> Spatiotemporal:
    """Spatiotemporal parameters of one trial.

    Parameters
    ----------
    events : GaitEvents
        Foot strikes and foot offs (e.g. from :func:`kisscal.gait.detect_events`).
    markers : GaitMarkers
        Heel trajectories give the positions at foot strike.

    Returns
    -------
    Spatiotemporal

    References
    ----------
    Perry 1992 (gait cycle phases); Winter 2009 (stride and step definitions).

    Examples
    --------
    >>> import numpy as np
    >>> from kisscal.gait.table import GaitEvents
    >>> from kisscal.gait.markers import GaitMarkers
    >>> t = np.arange(500) / 100.0
    >>> heel = {s: np.column_stack([1000.0 * t, np.full(500, y), np.zeros(500)])
    ...         for s, y in (("left", 50.0), ("right", -50.0))}
    >>> ev = GaitEvents.from_times({("left", "foot_strike"): [0.5, 1.5, 2.5],
    ...     ("right", "foot_strike"): [1.0, 2.0, 3.0], ("left", "foot_off"): [1.1, 2.1],
    ...     ("right", "foot_off"): [1.6, 2.6]}, 100.0)
    >>> gm = GaitMarkers((heel["left"],), heel, heel, 100.0, {})
    >>> st = spatiotemporal_parameters(ev, gm)
    >>> [round(st.mean(p, "left"), 3) for p in ("cadence", "stance", "double_support")]
    [120.0, 60.0, 20.0]
    >>> round(st.mean("step_width", "right"), 3), round(st.mean("step_length", "right"), 3)
    (0.1, 0.5)
    """
    rate = markers.rate_hz
    # Heel positions on the ground the subject walks on: on a treadmill the belt carries
    # the stance foot back, so a stride's length is the heel's displacement plus the
    # belt's (overground the ground is still and this changes nothing).
    belt = np.cumsum(ground_velocity(markers), axis=0) / rate
    heels = {s: markers.heel[s] - np.pad(belt, ((0, 0), (0, 1))) for s in SIDES}
    strikes = {s: events.times(s, "foot_strike") for s in SIDES}
    offs = {s: events.times(s, "foot_off") for s in SIDES}
    durations = np.concatenate([np.diff(strikes[s]) for s in SIDES])
    # a stride longer than 1.5 median strides hides a missed foot strike: not used
    limit = 1.5 * float(np.median(durations)) if len(durations) else 0.0
    values: dict[tuple[str, str], list[float]] = {(p, s): [] for p in UNITS for s in SIDES}
    for side in SIDES:
        other = _OTHER[side]
        heel = _at(heels[side], rate, strikes[side])
        for k in range(len(strikes[side]) - 1):
            t0, t1 = strikes[side][k], strikes[side][k + 1]
            if t1 - t0 > limit:
                continue
            _stride(values, side, t0, t1, heel[k], heel[k + 1], offs, strikes[other])
        other_heel = _at(heels[other], rate, strikes[other])
        for k, t in enumerate(strikes[side]):
            _step(values, side, t, heel[k], strikes[other], other_heel, limit)
    return Spatiotemporal({key: np.asarray(v, dtype=float) for key, v in values.items()})


def _stride(values: dict, side: str, t0: float, t1: float, h0, h1, offs: dict, other_strikes):
    duration = t1 - t0
    length = float(np.hypot(*(h1 - h0)[:2])) / 1000.0
    if np.isfinite(length):
        values[("stride_length", side)].append(length)
        values[("walking_speed", side)].append(length / duration)
    values[("stride_time", side)].append(duration)
    values[("cadence", side)].append(120.0 / duration)
    own_off = offs[side][(offs[side] > t0) & (offs[side] < t1)]
    if len(own_off) != 1:
        return
    stance = own_off[0] - t0
    values[("stance", side)].append(100.0 * stance / duration)
    values[("swing", side)].append(100.0 * (1.0 - stance / duration))
    other = _OTHER[side]
    other_off = offs[other][(offs[other] > t0) & (offs[other] < own_off[0])]
    other_on = other_strikes[(other_strikes > t0) & (other_strikes < own_off[0])]
    if len(other_off) == 1 and len(other_on) == 1 and other_off[0] < other_on[0]:
        double = (other_off[0] - t0) + (own_off[0] - other_on[0])
        values[("double_support", side)].append(100.0 * double / duration)


def _step(values: dict, side: str, t: float, heel, other_strikes, other_heel, limit: float):
    before = np.flatnonzero(other_strikes < t)
    after = np.flatnonzero(other_strikes > t)
    if not len(before) or not len(after):
        return
    i, j = before[-1], after[0]
    if other_strikes[j] - other_strikes[i] > limit:
        return
    values[("step_time", side)].append(t - other_strikes[i])
    a, b = other_heel[i][:2], other_heel[j][:2]
    line = b - a
    norm = float(np.hypot(*line))
    if not np.isfinite(norm) or norm == 0 or not np.all(np.isfinite(heel)):
        return
    u = line / norm
    rel = heel[:2] - a
    values[("step_length", side)].append(float(rel @ u) / 1000.0)
    values[("step_width", side)].append(abs(float(rel[0] * u[1] - rel[1] * u[0])) / 1000.0)
