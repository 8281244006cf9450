"""Cuts inside tracks: where a track's measured path is not smooth, and its stray ends.

The continuity test of blending (Shafiq et al. 2001 §4.3) applied within each track: a
track that took a neighbouring marker's point (a coasting gate, an initial track started
on a ghost) is cut there, so that blending and labelling see two pieces.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.tracks import MEASURED, Tracks


def _window_residuals(
    tracks: Tracks, side: int, stride: int = 1
) -> tuple[NDArray, NDArray, NDArray]:
    """RMS residual (mm) of a least-squares cubic (in the field index) through every run of
    ``2 * side`` consecutive measured samples of one track (every ``stride``-th run).

    Returns the rows of the measured samples, the window's first measured index per
    window, and the residual per window.
    """
    m = np.flatnonzero(tracks.status == MEASURED)
    w = 2 * side
    if m.size < w:
        return m, np.empty(0, dtype=np.int64), np.empty(0)
    first = np.arange(0, m.size - w + 1, stride)
    tr = tracks.track[m]
    first = first[tr[first] == tr[first + w - 1]]
    if first.size == 0:
        return m, first, np.empty(0)
    idx = first[:, None] + np.arange(w)
    f = tracks.field[m[idx]].astype(float)
    x = tracks.xyz_mm[m[idx]]
    residual = np.empty(first.size)
    # Windows without missing fields share one design matrix: their residual is a fixed
    # projection. The few with gaps are solved one by one in a batch.
    plain = f[:, -1] - f[:, 0] == w - 1
    t = (np.arange(w) - (w - 1) / 2) / side
    vander = t[:, None] ** np.arange(4)
    annihilate = np.eye(w) - vander @ np.linalg.pinv(vander)
    res = np.einsum("ij,njc->nic", annihilate, x[plain])
    residual[plain] = np.sqrt(np.mean(np.sum(res**2, axis=2), axis=1))
    if (~plain).any():
        fg = f[~plain]
        fg = (fg - fg.mean(axis=1, keepdims=True)) / side
        vg = fg[:, :, None] ** np.arange(4)
        vt = np.transpose(vg, (0, 2, 1))
        coef = np.linalg.solve(vt @ vg, vt @ x[~plain])
        residual[~plain] = np.sqrt(np.mean(np.sum((x[~plain] - vg @ coef) ** 2, axis=2), axis=1))
    return m, first, residual


def smoothness_mm(tracks: Tracks, side: int = 3) -> float:
    """Median cubic-fit residual of 6-sample windows over all tracks: the trial's own
    noise level (about the per-axis measurement noise), which scales the continuity
    tolerances so that noisier data are not cut into pieces. A median of at most about
    20 000 windows (evenly strided) is plenty."""
    n = int((tracks.status == MEASURED).sum())
    _, _, residual = _window_residuals(tracks, side, stride=max(1, n // 20000))
    return float(np.median(residual)) if residual.size else 0.0


def split_discontinuities(tracks: Tracks, tolerance_mm: float, side: int = 3) -> Tracks:
    """Split tracks where their measured path is not smooth (a jump to another marker).

    For every run of ``2 * side`` consecutive measured samples of a track, a cubic in the
    field index is fitted (least squares); where its RMS residual exceeds
    ``tolerance_mm`` and is the largest of the neighbouring windows, the track is cut
    between the two halves. This is blending's continuity test applied inside tracks: it
    catches a coasting gate or an initial track that took a neighbouring marker.
    """
    m, first, residual = _window_residuals(tracks, side)
    if residual.size == 0:
        return tracks
    # Residual per cut position (between measured samples i-1 and i).
    score = np.zeros(m.size)
    score[first + side] = residual
    neighbourhood = np.lib.stride_tricks.sliding_window_view(
        np.pad(score, side - 1), 2 * side - 1
    ).max(axis=1)
    cut = (score > tolerance_mm) & (score >= neighbourhood)
    if not cut.any():
        return tracks
    new_piece = np.zeros(tracks.field.size, dtype=np.int64)
    new_piece[m[cut]] = 1
    new_piece[1:] += tracks.track[1:] != tracks.track[:-1]
    piece = np.cumsum(new_piece)
    return tracks.with_track(piece)


#: A second stray end is another marker's when its offset from the path changed from the
#: first's by less than this share of itself (it moves with the path, beside it).
_OFFSET_CHANGE = 0.1


def split_stray_ends(
    tracks: Tracks, tolerance_mm: float, fit_points: int = 5, passes: int = 2
) -> Tracks:
    """Split off a track's first or last measured sample when the parabola through the
    next (previous) ``fit_points`` measured samples misses it by more than ``tolerance_mm``;
    the new end likewise, ``passes`` samples deep in all, where its offset from that
    parabola differs from the offset of the sample split off before it by less than
    :data:`_OFFSET_CHANGE` of itself.

    A track started on a ghost that lay where the real marker appeared next field (or
    ended on one) has a stray end that :func:`split_discontinuities` cannot see, for it
    needs three samples on each side of a cut. A young track that took another marker's
    point at its third sample has two such ends, and they move together beside the path
    (OptiTrack at 160 Hz: a marker seen for two fields, 3 mm apart, whose track then took
    a neighbour's point 22 mm from its prediction: offsets of 22.1 mm that differ by 0.3
    mm). A marker's own path that the parabola does not follow (a foot strike, a fast
    limb) leaves offsets that change with it: in the C3D regression set (49 files) by
    0.15 to 6.8 times their size, and no second end is split.
    """
    for from_end in (False, True):
        behind = (np.empty(0, dtype=np.int64), np.empty((0, 3)), np.empty(0))
        for k in range(passes):
            m = np.flatnonzero(tracks.status == MEASURED)
            if m.size < fit_points + 1:
                break
            tr = tracks.track[m]
            ids = np.arange(tracks.n_tracks)
            lo = np.searchsorted(tr, ids, "left")
            hi = np.searchsorted(tr, ids, "right")
            ok = hi - lo >= fit_points + 3
            edge = np.where(from_end, hi - 1, lo)[ok]
            step = -1 if from_end else 1
            fit = edge[:, None] + step * np.arange(1, fit_points + 1)
            f_fit = tracks.field[m[fit]].astype(float)
            f_edge = tracks.field[m[edge]].astype(float)
            centre = f_fit.mean(axis=1, keepdims=True)
            # A parabola: a cubic extrapolated one field amplifies noise five-fold.
            vander = ((f_fit - centre) / fit_points)[:, :, None] ** np.arange(3)
            vt = np.transpose(vander, (0, 2, 1))
            coef = np.linalg.solve(vt @ vander, vt @ tracks.xyz_mm[m[fit]])
            at = ((f_edge[:, None] - centre) / fit_points) ** np.arange(3)
            xyz = tracks.xyz_mm[m[edge]]
            off = xyz - np.einsum("nk,nkc->nc", at, coef)
            out = np.linalg.norm(off, axis=1) > tolerance_mm
            if k:  # a new end only, off the path as the sample split off before it was
                pos = np.searchsorted(behind[0], tracks.point[m[edge]])
                pos = np.minimum(pos, behind[0].size - 1)
                out &= behind[0][pos] == tracks.point[m[edge]]
                at = ((behind[2][pos, None] - centre) / fit_points) ** np.arange(3)
                was = behind[1][pos] - np.einsum("nk,nkc->nc", at, coef)
                change = np.linalg.norm(off - was, axis=1)
                out &= change < _OFFSET_CHANGE * np.linalg.norm(off, axis=1)
            if not out.any():
                break
            nxt = m[edge[out] + step]
            order = np.argsort(tracks.point[nxt])
            behind = (tracks.point[nxt][order], xyz[out][order], f_edge[out][order])
            piece = tracks.track.copy()
            piece[m[edge[out]]] = tracks.n_tracks + np.arange(int(out.sum()))
            tracks = tracks.with_track(piece)
    return tracks
