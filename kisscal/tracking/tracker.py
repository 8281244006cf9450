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
points left, rather than first-come nearest neighbour.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from kisscal.errors import KisscalError
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.predictors import (
    extrapolate,
    extrapolation_weights,
    gate_half_width,
    kalman_correct,
    kalman_predict,
)
from kisscal.tracking.tracks import MEASURED, PREDICTED, Tracks, make_tracks

_HISTORY = 5
_FAR = 1e12


def associate(
    predicted: NDArray, half_width: NDArray, points: NDArray, extra_cost: NDArray | None = None
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """One-to-one assignment of points to track gates.

    Parameters
    ----------
    predicted : (T, 3) predicted positions (mm).
    half_width : (T, 3) gate half-widths per axis (mm).
    points : (M, 3) candidate points (mm).
    extra_cost : (T, M) array, optional
        Added to the cost of each pair (e.g. a look-ahead term).

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
    cost = np.einsum("tmc,tmc->tm", scaled, scaled)
    if extra_cost is not None:
        cost = cost + extra_cost
    sub_inside = inside[np.ix_(rows_any, cols_any)]
    sub = np.where(sub_inside, cost[np.ix_(rows_any, cols_any)], _FAR)
    r, c = linear_sum_assignment(sub)
    keep = sub_inside[r, c]
    return rows_any[r[keep]], cols_any[c[keep]]


class _Live:
    """Struct of arrays for the tracks alive at the current field."""

    def __init__(self) -> None:
        self.ids = np.empty(0, dtype=np.int64)
        self.n = np.empty(0, dtype=np.int64)
        self.history = np.empty((0, _HISTORY, 3))
        self.state = np.empty((0, 3, 2))
        self.cov = np.empty((0, 2, 2))
        self.kalman = np.empty(0, dtype=bool)
        self.misses = np.empty(0, dtype=np.int64)

    def keep(self, mask: NDArray) -> None:
        for name in ("ids", "n", "history", "state", "cov", "kalman", "misses"):
            setattr(self, name, getattr(self, name)[mask])

    def add(self, ids: NDArray, xyz: NDArray) -> None:
        k = ids.size
        history = np.zeros((k, _HISTORY, 3))
        history[:, -1] = xyz
        self.ids = np.concatenate([self.ids, ids])
        self.n = np.concatenate([self.n, np.ones(k, dtype=np.int64)])
        self.history = np.concatenate([self.history, history])
        self.state = np.concatenate([self.state, np.zeros((k, 3, 2))])
        self.cov = np.concatenate([self.cov, np.zeros((k, 2, 2))])
        self.kalman = np.concatenate([self.kalman, np.zeros(k, dtype=bool)])
        self.misses = np.concatenate([self.misses, np.zeros(k, dtype=np.int64)])


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
    """
    field, xyz = _check_points(field, xyz_mm)
    order = np.argsort(field, kind="stable")
    sorted_field = field[order]
    if field.size == 0:
        e = np.empty(0)
        return make_tracks(e, e, np.empty((0, 3)), np.empty((0, 3)), e, e)
    first, last = int(sorted_field[0]), int(sorted_field[-1])
    starts = np.searchsorted(sorted_field, np.arange(first, last + 2))
    n_span = last - first + 1

    m_axes = np.asarray(params.gate_m)
    k_axes = np.asarray(params.gate_k_mm_per_field)
    n_init = params.min_initial_length
    w_pos = extrapolation_weights(n_init, 1, 0)
    w_vel = extrapolation_weights(n_init, 1, 1) - w_pos
    p0 = params.initial_error * np.eye(2)

    live = _Live()
    next_id = 0
    rec_track: list[NDArray] = []
    rec_point: list[NDArray] = []
    rec_xyz: list[NDArray] = []
    rec_corr: list[NDArray] = []
    rec_status: list[NDArray] = []
    rec_field: list[NDArray] = []

    for f in range(first, last + 1):
        idx = order[starts[f - first] : starts[f - first + 1]]
        points = xyz[idx]
        taken = np.zeros(idx.size, dtype=bool)
        n_live = live.ids.size
        measured = np.full((n_live, 3), np.nan)
        hit = np.zeros(n_live, dtype=bool)
        hit_point = np.full(n_live, -1, dtype=np.int64)
        if n_live:
            kal = live.kalman
            pred = np.empty((n_live, 3))
            half = np.empty((n_live, 3))
            if kal.any():
                live.state[kal], live.cov[kal] = kalman_predict(
                    live.state[kal], live.cov[kal], params.pnc
                )
                pred[kal] = live.state[kal, :, 0]
                drift = 0.5 * params.coast_accel_mm_per_field2 * ((live.misses[kal] + 1) ** 2 - 1)
                half[kal] = gate_half_width(live.state[kal, :, 1], m_axes, k_axes) + drift[:, None]
                if params.lag_widening:
                    # A filter with little process noise lags an accelerating marker; the
                    # distance from its prediction to Shafiq's five-point parabola through
                    # the track's last positions measures that lag, and widens the gate.
                    parabola = extrapolate(live.history[kal], live.n[kal])
                    half[kal] += np.abs(parabola - pred[kal])
            ini = ~kal
            if ini.any():
                pred[ini] = extrapolate(live.history[ini], live.n[ini])
                step = np.abs(pred[ini] - live.history[ini, -1])
                half[ini] = np.maximum(
                    params.initial_gate_factor * step, 0.5 * params.initial_gate_mm
                )
                half[ini & (live.n == 1)] = params.initial_gate_mm
            # Kalman tracks choose first; initial tracks take from what is left, those
            # with a velocity before those of one point.
            single = ini & (live.n == 1)
            for tier in (kal, ini & ~single, single):
                rows = np.flatnonzero(tier)
                if rows.size == 0:
                    continue
                free = np.flatnonzero(~taken)
                extra = None
                if tier is single and free.size:
                    later = xyz[order[starts[f - first + 1] : starts[min(f - first + 2, n_span)]]]
                    extra = lookahead_cost(
                        pred[rows], points[free], later, 0.5 * params.initial_gate_mm
                    )
                r, c = associate(pred[rows], half[rows], points[free], extra)
                hit[rows[r]] = True
                hit_point[rows[r]] = free[c]
                taken[free[c]] = True
            measured[hit] = points[hit_point[hit]]

            ends = ~hit & (~kal | (live.misses >= params.max_coasted_fields))
            coast = ~hit & kal & ~ends
            z = np.where(hit[:, None], measured, pred)
            if kal.any():
                # A missing point is replaced by the prediction, as if measured (§3.3.9).
                live.state[kal], live.cov[kal] = kalman_correct(
                    live.state[kal], live.cov[kal], z[kal], params.mnc
                )
            live.misses = np.where(hit, 0, live.misses + 1)
            live.history[:, :-1] = live.history[:, 1:]
            live.history[:, -1] = z
            live.n += 1

            born = hit & ~kal & (live.n >= n_init)
            if born.any():
                recent = live.history[born, -n_init:]
                live.state[born, :, 0] = np.einsum("k,tkc->tc", w_pos, recent)
                live.state[born, :, 1] = np.einsum("k,tkc->tc", w_vel, recent)
                live.cov[born] = p0
                live.kalman[born] = True

            out = hit | coast
            if out.any():
                rec_track.append(live.ids[out])
                point_row = np.full(int(out.sum()), -1, dtype=np.int64)
                hp = hit_point[out]
                point_row[hp >= 0] = idx[hp[hp >= 0]]
                rec_point.append(point_row)
                rec_xyz.append(z[out])
                corr = np.where(live.kalman[out, None], live.state[out, :, 0], np.nan)
                rec_corr.append(corr)
                rec_status.append(np.where(hit[out], MEASURED, PREDICTED).astype(np.int8))
                rec_field.append(np.full(int(out.sum()), f, dtype=np.int64))
            if ends.any():
                live.keep(~ends)
        new = np.flatnonzero(~taken)
        if new.size:
            ids = np.arange(next_id, next_id + new.size)
            next_id += new.size
            live.add(ids, points[new])
            rec_track.append(ids)
            rec_point.append(idx[new])
            rec_xyz.append(points[new])
            rec_corr.append(np.full((new.size, 3), np.nan))
            rec_status.append(np.zeros(new.size, dtype=np.int8))
            rec_field.append(np.full(new.size, f, dtype=np.int64))

    tracks = make_tracks(
        np.concatenate(rec_field),
        np.concatenate(rec_track),
        np.concatenate(rec_xyz),
        np.concatenate(rec_corr),
        np.concatenate(rec_status),
        np.concatenate(rec_point),
    )
    return split_short_reacquisitions(trim_predicted_ends(tracks), params.min_reacquired_fields)


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
