"""Gap filling and optional GCV smoothing of final trajectories.

Gaps inside a trajectory (blended gaps, and coasted fields whose Kalman prediction is
replaced by a two-sided estimate) are filled by a cubic interpolating spline through the
measured samples on both sides when short, and from the body (rigid-body or pattern fill,
:mod:`kisscal.tracking.bodyfill`) when longer. Smoothing uses the generalised
cross-validation spline (Woltring 1986, the biomechanics standard),
``scipy.interpolate.make_smoothing_spline``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import make_smoothing_spline

from kisscal.tracking.bodyfill import GapFill, body_fill, expected_error, spline_fill
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import FILLED, MEASURED, PREDICTED, Tracks, is_filled, make_tracks

_COLUMNS = ("field", "track", "xyz_mm", "corrected_mm", "status", "point")


def _runs(mask: NDArray) -> tuple[NDArray, NDArray]:
    """Start and stop (exclusive) of each run of True in a 1-D mask."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(padded)
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def _track_gaps(tracks: Tracks, rows: slice, params: TrackingParams) -> list[tuple[int, int]]:
    """(first field, stop field) of each gap of one track's ``rows`` to fill."""
    f = tracks.field[rows]
    status = tracks.status[rows]
    meas = status == MEASURED
    mf = f[meas]
    f0, f1 = mf[0], mf[-1]
    kept = meas | is_filled(status)
    if not params.refill_predicted:
        kept |= status == PREDICTED
    covered = np.zeros(f1 - f0 + 1, dtype=bool)
    inside = (f >= f0) & (f <= f1)
    covered[f[kept & inside] - f0] = True
    gap_lo, gap_hi = _runs(~covered)
    longest = max(params.max_fill_gap_fields, params.max_body_fill_fields)
    return [
        (int(lo + f0), int(hi + f0))
        for lo, hi in zip(gap_lo.tolist(), gap_hi.tolist(), strict=True)
        if hi - lo <= longest
    ]


def _fill_one(
    dense: NDArray, t: int, lo: int, hi: int, params: TrackingParams
) -> tuple[NDArray, GapFill] | None:
    """Spline for short gaps, the body (:func:`body_fill`) for longer ones."""
    if hi - lo <= params.max_fill_gap_fields:
        got = spline_fill(dense[t], dense, t, lo, hi, params)
        if got is None:
            return None
        err = expected_error(spline_fill, dense[t], dense, t, lo, hi, params)
        return got[0], GapFill(t, lo, hi - lo, FILLED, err)
    if hi - lo > params.max_body_fill_fields:
        return None
    return body_fill(dense, t, lo, hi, params)


def fill_gaps_logged(tracks: Tracks, params: TrackingParams) -> tuple[Tracks, tuple[GapFill, ...]]:
    """:func:`fill_gaps`, and how each gap was filled (method and expected error)."""
    if tracks.field.size == 0:
        return tracks, ()
    start, stop = tracks.bounds()
    meas = tracks.status == MEASURED
    n_fields = int(tracks.field.max()) + 1
    dense = np.full((tracks.n_tracks, n_fields, 3), np.nan)
    dense[tracks.track[meas], tracks.field[meas]] = tracks.xyz_mm[meas]
    fills, filled_xyz = [], []
    for t in range(tracks.n_tracks):
        for lo, hi in _track_gaps(tracks, slice(start[t], stop[t]), params):
            got = _fill_one(dense, t, lo, hi, params)
            if got is not None:
                filled_xyz.append(got[0])
                fills.append(got[1])
    if not fills:
        return make_tracks(*(getattr(tracks, c) for c in _COLUMNS)), ()
    new_field = np.concatenate([g.first_field + np.arange(g.n_fields) for g in fills])
    new_track = np.concatenate([np.full(g.n_fields, g.track) for g in fills])
    new_status = np.concatenate([np.full(g.n_fields, g.status, dtype=np.int8) for g in fills])
    # A filled sample replaces the track's sample there (a Kalman prediction).
    replaced = np.zeros(tracks.n_tracks * n_fields, dtype=bool)
    replaced[new_track * n_fields + new_field] = True
    keep = ~replaced[tracks.track * n_fields + tracks.field]
    n = new_field.size
    out = make_tracks(
        np.concatenate([tracks.field[keep], new_field]),
        np.concatenate([tracks.track[keep], new_track]),
        np.concatenate([tracks.xyz_mm[keep], *filled_xyz]),
        np.concatenate([tracks.corrected_mm[keep], np.full((n, 3), np.nan)]),
        np.concatenate([tracks.status[keep], new_status]),
        np.concatenate([tracks.point[keep], np.full(n, -1)]),
    )
    return out, tuple(fills)


def fill_gaps(tracks: Tracks, params: TrackingParams) -> Tracks:
    """Fill the gaps inside each track: short ones by a spline, longer ones from the body.

    A gap is a run of fields between a track's first and last measured sample without a
    measured sample (or, with ``refill_predicted``, with only a Kalman prediction). Gaps of
    at most ``max_fill_gap_fields`` are filled by a cubic spline
    (``scipy.interpolate.make_interp_spline``) through up to ``fill_context_fields``
    measured samples on each side (status ``filled_spline``); longer ones, up to
    ``max_body_fill_fields``, by rigid-body or pattern fill when the trial supports one
    (:func:`~kisscal.tracking.bodyfill.body_fill`; status ``filled_rigid`` or
    ``filled_pattern``). Filled samples' ``corrected_mm`` is NaN.

    References
    ----------
    Gløersen & Federolf 2016 (filling from the other markers of the body).
    """
    return fill_gaps_logged(tracks, params)[0]


def smooth_tracks(tracks: Tracks, min_run: int = 5) -> Tracks:
    """Smooth each run of consecutive fields of every track with a GCV smoothing spline.

    The smoothing parameter is chosen per run and per axis set by generalised
    cross-validation (Woltring 1986; ``make_smoothing_spline`` with ``lam=None``). Runs
    shorter than ``min_run`` fields are left as they are. Statuses are unchanged.
    """
    xyz = tracks.xyz_mm.copy()
    if tracks.field.size == 0:
        return tracks
    brk = np.flatnonzero((np.diff(tracks.field) != 1) | (np.diff(tracks.track) != 0)) + 1
    lo = np.r_[0, brk]
    hi = np.r_[brk, tracks.field.size]
    for a, b in zip(lo, hi, strict=True):
        if b - a < min_run:
            continue
        x = tracks.field[a:b].astype(float)
        for axis in range(3):
            xyz[a:b, axis] = make_smoothing_spline(x, xyz[a:b, axis])(x)
    return Tracks(tracks.field, tracks.track, xyz, tracks.corrected_mm, tracks.status, tracks.point)
