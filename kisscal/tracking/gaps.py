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


def _runs(mask: NDArray) -> tuple[NDArray, NDArray]:
    """Start and stop (exclusive) of each run of True in a 1-D mask."""
    padded = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(padded)
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


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
    fields_out, track_out, xyz_out, corr_out, status_out, point_out = [], [], [], [], [], []
    ctx = max(params.fill_context_fields, 2)
    for t in range(tracks.n_tracks):
        rows = slice(start[t], stop[t])
        f = tracks.field[rows]
        status = tracks.status[rows]
        meas = status == MEASURED
        f0, f1 = f[meas][0], f[meas][-1]
        span = f1 - f0 + 1
        present = np.zeros(span, dtype=bool)
        present[f[meas] - f0] = True
        kept = meas | (status == FILLED)
        if not params.refill_predicted:
            kept |= status == PREDICTED
        covered = np.zeros(span, dtype=bool)
        inside = (f >= f0) & (f <= f1)
        covered[f[kept & inside] - f0] = True
        gap_lo, gap_hi = _runs(~covered)
        new_f: list[NDArray] = []
        new_xyz: list[NDArray] = []
        mf = f[meas]
        mxyz = tracks.xyz_mm[rows][meas]
        for lo, hi in zip(gap_lo, gap_hi, strict=True):
            if hi - lo > params.max_fill_gap_fields:
                continue
            gap_fields = np.arange(lo, hi) + f0
            i = np.searchsorted(mf, gap_fields[0])
            sel = np.arange(max(i - ctx, 0), min(i + ctx, mf.size))
            k = min(3, sel.size - 1)
            spline = make_interp_spline(mf[sel], mxyz[sel], k=k)
            new_f.append(gap_fields)
            new_xyz.append(spline(gap_fields))
        drop = np.zeros(f.size, dtype=bool)
        if new_f:
            filled_fields = np.concatenate(new_f)
            drop = np.isin(f, filled_fields)
        keep_rows = np.flatnonzero(~drop) + start[t]
        fields_out.append(tracks.field[keep_rows])
        track_out.append(tracks.track[keep_rows])
        xyz_out.append(tracks.xyz_mm[keep_rows])
        corr_out.append(tracks.corrected_mm[keep_rows])
        status_out.append(tracks.status[keep_rows])
        point_out.append(tracks.point[keep_rows])
        if new_f:
            n = filled_fields.size
            fields_out.append(filled_fields)
            track_out.append(np.full(n, t))
            xyz_out.append(np.concatenate(new_xyz))
            corr_out.append(np.full((n, 3), np.nan))
            status_out.append(np.full(n, FILLED, dtype=np.int8))
            point_out.append(np.full(n, -1))
    return make_tracks(
        np.concatenate(fields_out),
        np.concatenate(track_out),
        np.concatenate(xyz_out),
        np.concatenate(corr_out),
        np.concatenate(status_out),
        np.concatenate(point_out),
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
