"""Gap filling and optional GCV smoothing of final trajectories.

Gaps inside a trajectory (blended gaps, and coasted fields whose Kalman prediction is
replaced by a two-sided estimate) are filled by a cubic interpolating spline through the
measured samples on both sides. Smoothing uses the generalised cross-validation spline
(Woltring 1986, the biomechanics standard), ``scipy.interpolate.make_smoothing_spline``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.interpolate import make_interp_spline, make_smoothing_spline

from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import FILLED, MEASURED, PREDICTED, Tracks, make_tracks

_COLUMNS = ("field", "track", "xyz_mm", "corrected_mm", "status", "point")


def _runs(mask: NDArray) -> tuple[NDArray, NDArray]:
    """Start and stop (exclusive) of each run of True in a 1-D mask."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(padded)
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def _track_gaps(tracks: Tracks, rows: slice, params: TrackingParams) -> list[tuple[NDArray, ...]]:
    """(gap fields, filled positions) of each gap of one track's ``rows`` to fill."""
    f = tracks.field[rows]
    status = tracks.status[rows]
    meas = status == MEASURED
    mf = f[meas]
    f0, f1 = mf[0], mf[-1]
    kept = meas | (status == FILLED)
    if not params.refill_predicted:
        kept |= status == PREDICTED
    covered = np.zeros(f1 - f0 + 1, dtype=bool)
    inside = (f >= f0) & (f <= f1)
    covered[f[kept & inside] - f0] = True
    gap_lo, gap_hi = _runs(~covered)
    if gap_lo.size == 0:
        return []
    ctx = max(params.fill_context_fields, 2)
    mxyz = tracks.xyz_mm[rows][meas]
    out = []
    for lo, hi in zip(gap_lo.tolist(), gap_hi.tolist(), strict=True):
        if hi - lo > params.max_fill_gap_fields:
            continue
        gap_fields = np.arange(lo, hi) + f0
        i = int(np.searchsorted(mf, gap_fields[0]))
        sel = slice(max(i - ctx, 0), min(i + ctx, mf.size))
        k = min(3, sel.stop - sel.start - 1)
        out.append((gap_fields, make_interp_spline(mf[sel], mxyz[sel], k=k)(gap_fields)))
    return out


def fill_gaps(tracks: Tracks, params: TrackingParams) -> Tracks:
    """Fill gaps of at most ``max_fill_gap_fields`` inside each track.

    A gap is a run of fields between a track's first and last measured sample without a
    measured sample (or, with ``refill_predicted``, with only a Kalman prediction). It is
    filled by a cubic spline (``scipy.interpolate.make_interp_spline``) through up to
    ``fill_context_fields`` measured samples on each side; filled samples get status
    ``filled``, and their ``corrected_mm`` is NaN.
    """
    if tracks.field.size == 0:
        return tracks
    start, stop = tracks.bounds()
    filled_fields, filled_track, filled_xyz = [], [], []
    for t in range(tracks.n_tracks):
        for gap_fields, xyz in _track_gaps(tracks, slice(start[t], stop[t]), params):
            filled_fields.append(gap_fields)
            filled_track.append(np.full(gap_fields.size, t))
            filled_xyz.append(xyz)
    if not filled_fields:
        return make_tracks(*(getattr(tracks, c) for c in _COLUMNS))
    new_field = np.concatenate(filled_fields)
    new_track = np.concatenate(filled_track)
    # A filled sample replaces the track's sample there (a Kalman prediction).
    n_fields = int(max(tracks.field.max(), new_field.max())) + 1
    replaced = np.zeros(tracks.n_tracks * n_fields, dtype=bool)
    replaced[new_track * n_fields + new_field] = True
    keep = ~replaced[tracks.track * n_fields + tracks.field]
    n = new_field.size
    return make_tracks(
        np.concatenate([tracks.field[keep], new_field]),
        np.concatenate([tracks.track[keep], new_track]),
        np.concatenate([tracks.xyz_mm[keep], *filled_xyz]),
        np.concatenate([tracks.corrected_mm[keep], np.full((n, 3), np.nan)]),
        np.concatenate([tracks.status[keep], np.full(n, FILLED, dtype=np.int8)]),
        np.concatenate([tracks.point[keep], np.full(n, -1)]),
    )


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
