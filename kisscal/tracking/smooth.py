"""Smoothing the measured runs of every track (Woltring 1986: a smoothing spline whose
parameter generalised cross-validation chooses).

References
----------
Woltring 1986, A Fortran package for generalized, cross-validatory spline smoothing
and differentiation, Advances in Engineering Software 8(2).
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import make_smoothing_spline

from kisscal.tracking.tracks import Tracks


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
