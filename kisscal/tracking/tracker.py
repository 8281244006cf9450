"""Forward tracking of 3D points field by field (Küçük 2005 §3.3.8-3.3.9).

Each new point starts an *initial track*, extended by Shafiq's extrapolators (one point:
the point itself is the prediction; two: linear; three or four: least-squares line) and the
nearest point in its search region; an initial track without a point in its region ends.
Once an initial track has ``min_initial_length`` points, three constant-velocity Kalman
filters (one per axis) are initialised on it and take over: each field they predict, a box
gate of half-width f(v) per axis (eq. 3.16) is placed around the prediction, and the point
in the gate becomes the measurement. With an empty gate the prediction stands in for the
missing point (recorded as ``predicted``); after ``max_coasted_fields`` consecutive misses
the track ends and its trailing predictions are dropped.

Association is one-to-one over all tracks of a field (``scipy.optimize.linear_sum_assignment``
on gate-normalised squared distances), Kalman tracks first, then initial tracks on the
points left, rather than first-come nearest neighbour. A one-point track looks one field
ahead (offline, the next field is known) to tell which candidate continues.

The pieces are then checked, because a gate can take the wrong point: a short run of
points after coasting is split off (a ghost caught after the marker left), and a track is
cut where its path is not smooth (a cubic through three samples on each side misses them)
or where its first or last point strays from the rest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from kisscal.errors import KisscalError
from kisscal.tracking.blending import smoothness_mm, split_discontinuities, split_stray_ends
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.predictors import (
    extrapolation_weights,
    gate_half_width,
    kalman_correct,
    kalman_predict,
    shafiq_rule,
)
from kisscal.tracking.tracks import MEASURED, PREDICTED, Tracks, make_tracks

_HISTORY = 5
_SINGLE_STEP_WEIGHT = 0.1
_FAR = 1e12


def associate(
    predicted: NDArray,
    half_width: NDArray,
    points: NDArray,
    extra_cost: NDArray | None = None,
    distance_weight: float = 1.0,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """One-to-one assignment of points to track gates.

    Parameters
    ----------
    predicted : (T, 3) predicted positions (mm).
    half_width : (T, 3) gate half-widths per axis (mm).
    points : (M, 3) candidate points (mm).
    extra_cost : (T, M) array, optional
        Added to the cost of each pair (e.g. a look-ahead term).
    distance_weight : float
        Weight of the gate-normalised squared distance in the cost.

    Returns
    -------
    rows, cols : matched track and point indices; every pair lies inside its box gate and
    the sum of gate-normalised squared distances is minimal over all one-to-one matchings.
    """
    if predicted.shape[0] == 0 or points.shape[0] == 0:
        empty = np.empty(0, dtype=np.int64)
        return empty, empty
    scaled = (points[None, :, :] - predicted[:, None, :]) / half_width[:, None, :]
    inside = (np.abs(scaled) <= 1.0).all(axis=2)
    rows_any = np.flatnonzero(inside.any(axis=1))
    cols_any = np.flatnonzero(inside.any(axis=0))
    if rows_any.size == 0:
        empty = np.empty(0, dtype=np.int64)
        return empty, empty
    cost = distance_weight * np.einsum("tmc,tmc->tm", scaled, scaled)
    if extra_cost is not None:
        cost = cost + extra_cost
    sub_inside = inside[np.ix_(rows_any, cols_any)]
    sub = np.where(sub_inside, cost[np.ix_(rows_any, cols_any)], _FAR)
    r, c = linear_sum_assignment(sub)
    keep = sub_inside[r, c]
    return rows_any[r[keep]], cols_any[c[keep]]


class _Live:
    """Struct of arrays for the tracks alive at the current field, with spare rows.

    Every row is computed on each field whether alive or not: on a few dozen rows one
    numpy call costs the same as on the live ones, and it spares gathers and scatters.
    """

    def __init__(self, capacity: int = 64) -> None:
        self.ids = np.full(capacity, -1, dtype=np.int64)
        self.n = np.ones(capacity, dtype=np.int64)
        self.history = np.zeros((capacity, _HISTORY, 3))
        self.state = np.zeros((capacity, 3, 2))
        self.cov = np.tile(np.eye(2), (capacity, 1, 1))
        self.kalman = np.zeros(capacity, dtype=bool)
        self.misses = np.zeros(capacity, dtype=np.int64)
        self.alive = np.zeros(capacity, dtype=bool)

    def add(self, ids: NDArray, xyz: NDArray) -> None:
        slots = np.flatnonzero(~self.alive)
        if slots.size < ids.size:
            self._grow(ids.size - slots.size)
            slots = np.flatnonzero(~self.alive)
        slots = slots[: ids.size]
        self.ids[slots] = ids
        self.n[slots] = 1
        self.history[slots] = 0.0
        self.history[slots, -1] = xyz
        self.state[slots] = 0.0
        self.cov[slots] = np.eye(2)
        self.kalman[slots] = False
        self.misses[slots] = 0
        self.alive[slots] = True

    def _grow(self, extra: int) -> None:
        more = max(extra, self.ids.size)
        self.ids = np.r_[self.ids, np.full(more, -1, dtype=np.int64)]
        self.n = np.r_[self.n, np.ones(more, dtype=np.int64)]
        self.history = np.concatenate([self.history, np.zeros((more, _HISTORY, 3))])
        self.state = np.concatenate([self.state, np.zeros((more, 3, 2))])
        self.cov = np.concatenate([self.cov, np.tile(np.eye(2), (more, 1, 1))])
        self.kalman = np.r_[self.kalman, np.zeros(more, dtype=bool)]
        self.misses = np.r_[self.misses, np.zeros(more, dtype=np.int64)]
        self.alive = np.r_[self.alive, np.zeros(more, dtype=bool)]


def _shafiq_weights(ahead: int = 1) -> NDArray[np.float64]:
    """(6, 5) weights: row n applies Shafiq's extrapolator for a track of n points
    (n >= 5 in the last row) to its last five positions (oldest first)."""
    out = np.zeros((_HISTORY + 1, _HISTORY))
    for n in range(1, _HISTORY + 1):
        used, degree = shafiq_rule(n)
        out[n, _HISTORY - used :] = extrapolation_weights(used, degree, ahead)
    return out


def lookahead_cost(
    start: NDArray, candidates: NDArray, later: NDArray, half_width: float
) -> NDArray[np.float64]:
    """Cost of continuing one-point tracks through each candidate, judged one field on.

    A track with one point has no velocity, so its nearest next point may be another
    marker (a heel marker moving into the place an ankle marker just left). Offline, the
    field after next is known: the pair (start, candidate) is extrapolated linearly
    (thesis eq. 3.11) and the squared distance of the nearest point there, in units of
    ``half_width``, is the cost (capped at 4 when nothing is near).

    Returns (T, M) for ``start`` (T, 3), ``candidates`` (M, 3), ``later`` (K, 3).
    """
    if later.shape[0] == 0:
        return np.zeros((start.shape[0], candidates.shape[0]))
    ahead = 2.0 * candidates[None, :, :] - start[:, None, :]  # (T, M, 3)
    d2 = ((ahead[:, :, None, :] - later[None, None, :, :]) ** 2).sum(axis=3).min(axis=2)
    return np.minimum(d2 / half_width**2, 4.0)


def _check_points(field: ArrayLike, xyz_mm: ArrayLike) -> tuple[NDArray, NDArray]:
    field = np.asarray(field)
    xyz = np.asarray(xyz_mm, dtype=float)
    if field.ndim != 1 or xyz.shape != (field.size, 3):
        raise KisscalError(
            f"tracking: need field (N,) and xyz_mm (N, 3), got {field.shape} and {xyz.shape}"
        )
    if field.size and (
        not np.issubdtype(field.dtype, np.integer) and not np.all(field == np.round(field))
    ):
        raise KisscalError("tracking: field indices must be whole numbers")
    if field.size and field.min() < 0:
        raise KisscalError("tracking: field indices must be >= 0")
    if not np.isfinite(xyz).all():
        raise KisscalError("tracking: xyz_mm contains NaN or infinite values")
    return field.astype(np.int64), xyz


class _Recorder:
    """The samples tracking emits, gathered field by field; :meth:`tracks` makes the table."""

    def __init__(self) -> None:
        self._parts: list[tuple[NDArray, ...]] = []

    def add(
        self,
        field: int,
        track: NDArray,
        point: NDArray,
        xyz: NDArray,
        corrected: NDArray,
        status: NDArray,
    ) -> None:
        """Record one sample per entry of ``track`` at ``field``."""
        field_col = np.full(track.size, field, dtype=np.int64)
        self._parts.append((field_col, track, xyz, corrected, status.astype(np.int8), point))

    def tracks(self) -> Tracks:
        return make_tracks(*(np.concatenate(col) for col in zip(*self._parts, strict=True)))


@dataclass(frozen=True)
class _Setup:
    """What every field's step needs from the parameters, computed once."""

    params: TrackingParams
    m_axes: NDArray
    k_axes: NDArray
    w_pos: NDArray
    w_vel: NDArray
    p0: NDArray
    shafiq: NDArray

    @classmethod
    def of(cls, params: TrackingParams) -> _Setup:
        n_init = params.min_initial_length
        w_pos = extrapolation_weights(n_init, 1, 0)
        return cls(
            params,
            np.asarray(params.gate_m),
            np.asarray(params.gate_k_mm_per_field),
            w_pos,
            extrapolation_weights(n_init, 1, 1) - w_pos,
            params.initial_error * np.eye(2),
            _shafiq_weights(),
        )


def _predict(live: _Live, setup: _Setup) -> tuple[NDArray, NDArray, NDArray]:
    """Predicted position and gate half-widths (T, 3) of every row, and which rows are
    one-point tracks (no velocity yet)."""
    params = setup.params
    # Predictions of every row: Kalman (thesis eq. 3.14) and Shafiq's extrapolator.
    live.state, live.cov = kalman_predict(live.state, live.cov, params.pnc)
    kal = live.kalman
    parabola = np.einsum("tk,tkc->tc", setup.shafiq[np.minimum(live.n, _HISTORY)], live.history)
    pred = np.where(kal[:, None], live.state[:, :, 0], parabola)
    drift = 0.5 * params.coast_accel_mm_per_field2 * ((live.misses + 1) ** 2 - 1)
    half_kalman = gate_half_width(live.state[:, :, 1], setup.m_axes, setup.k_axes) + drift[:, None]
    if params.lag_widening:
        # A filter with little process noise lags an accelerating marker; the distance
        # from its prediction to Shafiq's five-point parabola through the track's last
        # positions measures that lag, and widens the gate.
        half_kalman = half_kalman + np.abs(parabola - live.state[:, :, 0])
    half_initial = np.maximum(
        params.initial_gate_factor * np.abs(parabola - live.history[:, -1]),
        0.5 * params.initial_gate_mm,
    )
    single = ~kal & (live.n == 1)
    half = np.where(kal[:, None], half_kalman, half_initial)
    half[single] = params.initial_gate_mm
    return pred, half, single


def _gate(
    live: _Live,
    pred: NDArray,
    half: NDArray,
    single: NDArray,
    points: NDArray,
    later: NDArray,
    params: TrackingParams,
) -> tuple[NDArray, NDArray, NDArray]:
    """Which rows found a point in their gate, which point (-1: none) and which points
    were taken."""
    kal = live.kalman
    rows_alive = np.flatnonzero(live.alive)
    taken = np.zeros(points.shape[0], dtype=bool)
    hit = np.zeros(kal.size, dtype=bool)
    hit_point = np.full(kal.size, -1, dtype=np.int64)
    if not points.shape[0]:
        return hit, hit_point, taken
    scaled = (points[None, :, :] - pred[rows_alive, None, :]) / half[rows_alive, None, :]
    inside = (np.abs(scaled) <= 1.0).all(axis=2)
    if inside.sum(axis=0).max() <= 1 and inside.sum(axis=1).max() <= 1:
        # No point is wanted by two gates and no gate holds two points: the assignment
        # is the gating itself.
        r, c = np.nonzero(inside)
        hit[rows_alive[r]] = True
        hit_point[rows_alive[r]] = c
        taken[c] = True
        return hit, hit_point, taken
    # Kalman tracks choose first; initial tracks take from what is left, those with a
    # velocity before those of one point.
    for tier in (kal, ~kal & ~single, single):
        rows = rows_alive[tier[rows_alive]]
        free = np.flatnonzero(~taken)
        if rows.size == 0 or free.size == 0:
            continue
        extra = None
        if tier is single:
            extra = lookahead_cost(pred[rows], points[free], later, 0.5 * params.initial_gate_mm)
        # A one-point track has no velocity: how far the candidate lies says little (a
        # fast foot moves more than a slow marker's neighbour is away); whether the pair
        # continues says much.
        weight = _SINGLE_STEP_WEIGHT if extra is not None else 1.0
        r, c = associate(pred[rows], half[rows], points[free], extra, weight)
        hit[rows[r]] = True
        hit_point[rows[r]] = free[c]
        taken[free[c]] = True
    return hit, hit_point, taken


def _update(
    live: _Live, setup: _Setup, pred: NDArray, hit: NDArray, hit_point: NDArray, points: NDArray
) -> tuple[NDArray, NDArray, NDArray]:
    """Correct the filters with the points found (or the predictions, §3.3.9), start
    filters on initial tracks long enough; returns the positions used and the rows that
    end and that coast."""
    params = setup.params
    kal, alive = live.kalman, live.alive
    ends = alive & ~hit & (~kal | (live.misses >= params.max_coasted_fields))
    coast = alive & ~hit & kal & ~ends
    z = pred.copy()
    z[hit] = points[hit_point[hit]]
    # A missing point is replaced by the prediction, as if measured (§3.3.9).
    live.state, live.cov = kalman_correct(live.state, live.cov, z, params.mnc)
    live.misses = np.where(hit, 0, live.misses + 1)
    live.history[:, :-1] = live.history[:, 1:]
    live.history[:, -1] = z
    live.n += 1
    n_init = params.min_initial_length
    born = hit & ~kal & (live.n >= n_init)
    if born.any():
        recent = live.history[born, -n_init:]
        live.state[born, :, 0] = np.einsum("k,tkc->tc", setup.w_pos, recent)
        live.state[born, :, 1] = np.einsum("k,tkc->tc", setup.w_vel, recent)
        live.cov[born] = setup.p0
        live.kalman[born] = True
    return z, ends, coast


def _step(
    live: _Live, setup: _Setup, rec: _Recorder, f: int, idx: NDArray, points: NDArray, later
) -> NDArray[np.bool_]:
    """Extend the live tracks by field ``f``'s points; returns which points were taken."""
    pred, half, single = _predict(live, setup)
    hit, hit_point, taken = _gate(live, pred, half, single, points, later, setup.params)
    z, ends, coast = _update(live, setup, pred, hit, hit_point, points)
    out = np.flatnonzero(hit | coast)
    if out.size:
        hp = hit_point[out]
        rec.add(
            f,
            live.ids[out],
            np.where(hp >= 0, idx[np.maximum(hp, 0)] if idx.size else -1, -1),
            z[out],
            np.where(live.kalman[out, None], live.state[out, :, 0], np.nan),
            np.where(hit[out], MEASURED, PREDICTED),
        )
    live.alive &= ~ends
    return taken


def track_points(field: ArrayLike, xyz_mm: ArrayLike, params: TrackingParams) -> Tracks:
    """Form track pieces from 3D points per field (Küçük 2005 §3.3.8-3.3.9).

    Parameters
    ----------
    field : (N,) int array
        Field index of each 3D point (any order).
    xyz_mm : (N, 3) float array
        Lab coordinates of the points (mm).
    params : TrackingParams
        Kalman noise, gate and coasting parameters.

    Returns
    -------
    Tracks
        Every piece, including short ghost pieces (see :func:`clean_up`), with samples
        ``measured`` or ``predicted`` (coasted fields followed by a measurement).

    References
    ----------
    Küçük 2005 (Kalman tracking, gate eq. 3.16, coasting); Shafiq et al. 2001 (the
    extrapolators of initial tracks).
    """
    field, xyz = _check_points(field, xyz_mm)
    if field.size == 0:
        e = np.empty(0)
        return make_tracks(e, e, np.empty((0, 3)), np.empty((0, 3)), e, e)
    order = np.argsort(field, kind="stable")
    sorted_field = field[order]
    first, last = int(sorted_field[0]), int(sorted_field[-1])
    starts = np.searchsorted(sorted_field, np.arange(first, last + 2))
    n_span = last - first + 1
    setup = _Setup.of(params)
    live = _Live()
    rec = _Recorder()
    next_id = 0
    for f in range(first, last + 1):
        idx = order[starts[f - first] : starts[f - first + 1]]
        points = xyz[idx]
        taken = np.zeros(idx.size, dtype=bool)
        if live.alive.any():
            later = xyz[order[starts[f - first + 1] : starts[min(f - first + 2, n_span)]]]
            taken = _step(live, setup, rec, f, idx, points, later)
        new = np.flatnonzero(~taken)
        if new.size:
            ids = np.arange(next_id, next_id + new.size)
            next_id += new.size
            live.add(ids, points[new])
            no_filter = np.full((new.size, 3), np.nan)
            rec.add(f, ids, idx[new], points[new], no_filter, np.zeros(new.size))
    tracks = split_short_reacquisitions(
        trim_predicted_ends(rec.tracks()), params.min_reacquired_fields
    )
    tolerance = max(params.split_tolerance_mm, params.split_noise_factor * smoothness_mm(tracks))
    # One-sided extrapolation is twice as uncertain as the two-sided fit.
    tracks = split_stray_ends(split_discontinuities(tracks, tolerance), 2.0 * tolerance)
    return trim_predicted_ends(tracks)


def split_short_reacquisitions(tracks: Tracks, min_run: int) -> Tracks:
    """Split off runs of fewer than ``min_run`` measured fields that follow a coasted field.

    A coasting gate that catches a ghost after the marker has gone (out of view, or hidden
    for long) would otherwise extend the track with wrong points, while a real marker found
    again keeps being found. Such a run becomes a piece of its own: blending reconnects it
    if it continues the track, the clean-up removes it if not.
    """
    for _ in range(8):
        if tracks.field.size == 0 or min_run <= 1:
            return tracks
        meas = tracks.status == MEASURED
        same = np.r_[False, tracks.track[1:] == tracks.track[:-1]]
        consecutive = same & np.r_[False, np.diff(tracks.field) == 1]
        run_start = meas & ~(consecutive & np.r_[False, meas[:-1]])
        run_id = np.cumsum(run_start) - 1
        run_len = np.bincount(run_id[meas], minlength=int(run_start.sum()))
        after_coast = run_start & same & np.r_[False, tracks.status[:-1] == PREDICTED]
        short_runs = np.zeros(run_len.size, dtype=bool)
        short_runs[run_id[after_coast]] = run_len[run_id[after_coast]] < min_run
        split = meas & short_runs[np.maximum(run_id, 0)]
        if not split.any():
            return tracks
        # New piece numbers for the split runs, beyond every existing number.
        new_track = np.where(split, tracks.n_tracks + run_id, tracks.track)
        # Predictions between the track and the split run now end the track: drop them.
        tracks = trim_predicted_ends(
            make_tracks(
                tracks.field,
                new_track,
                tracks.xyz_mm,
                tracks.corrected_mm,
                tracks.status,
                tracks.point,
            )
        )
    return tracks


def trim_predicted_ends(tracks: Tracks) -> Tracks:
    """Drop predicted samples after a track's last measured sample (coasting that never
    found the marker again)."""
    if tracks.field.size == 0:
        return tracks
    last = np.full(tracks.n_tracks, -1, dtype=np.int64)
    m = tracks.status == MEASURED
    np.maximum.at(last, tracks.track[m], tracks.field[m])
    return tracks.select(tracks.field <= last[tracks.track])
