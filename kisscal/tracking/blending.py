"""Blending of track pieces and clean-up of short tracks (Shafiq et al. 2001 §4.3).

Pieces that end and start within a few fields are connectable; continuity is checked by
extrapolating each piece across the gap with the extrapolator its length allows (two-point
line, three-point least-squares line, five-point parabola), forward from the end of the
first and backward from the start of the second. Accepted pairs are chosen one-to-one
(``linear_sum_assignment``) and chained. The clean-up then removes tracks with too few
measured points: most ghost tracks are short.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from kisscal.tracking.params import TrackingParams
from kisscal.tracking.predictors import extrapolation_weights, shafiq_rule
from kisscal.tracking.tracks import MEASURED, Tracks

_FAR = 1e12


def _end_points(tracks: Tracks, from_end: bool) -> tuple[NDArray, NDArray, NDArray]:
    """Field of the first/last measured sample per track, its last/first up to 5 measured
    positions (nearest last) and how many there are."""
    n = tracks.n_tracks
    m = np.flatnonzero(tracks.status == MEASURED)
    tr = tracks.track[m]
    start = np.searchsorted(tr, np.arange(n), "left")
    stop = np.searchsorted(tr, np.arange(n), "right")
    count = np.minimum(stop - start, 5)
    history = np.zeros((n, 5, 3))
    for j in range(5):
        # j-th point counted from the piece's end (or start), placed nearest-last.
        ok = count > j
        rows = (stop - 1 - j) if from_end else (start + j)
        history[ok, 4 - j] = tracks.xyz_mm[m[rows[ok]]]
    edge = tracks.field[m[np.where(from_end, stop - 1, start)]] if n else np.empty(0, int)
    return edge, history, count


def _extrapolate_gap(history: NDArray, count: NDArray, ahead: NDArray) -> NDArray:
    out = np.empty((history.shape[0], 3))
    for i in range(history.shape[0]):
        used, degree = shafiq_rule(int(count[i]))
        w = extrapolation_weights(used, degree, int(ahead[i]))
        out[i] = w @ history[i, -used:]
    return out


def blend_pairs(tracks: Tracks, params: TrackingParams) -> tuple[NDArray, NDArray]:
    """Pairs (earlier piece, later piece) that blending connects.

    A later piece must start 1 .. ``blend_gap_fields + 1`` fields after the earlier one
    ends, and both extrapolations across the gap must land within
    ``blend_tolerance_mm`` (times the number of fields crossed) of the other piece.
    """
    if tracks.n_tracks < 2:
        e = np.empty(0, dtype=np.int64)
        return e, e
    end_field, end_hist, end_n = _end_points(tracks, from_end=True)
    start_field, start_hist, start_n = _end_points(tracks, from_end=False)
    step = start_field[None, :] - end_field[:, None]
    a, b = np.nonzero((step >= 1) & (step <= params.blend_gap_fields + 1))
    if a.size == 0:
        e = np.empty(0, dtype=np.int64)
        return e, e
    ahead = step[a, b]
    forward = _extrapolate_gap(end_hist[a], end_n[a], ahead)
    backward = _extrapolate_gap(start_hist[b], start_n[b], ahead)
    miss_f = np.linalg.norm(forward - start_hist[b, -1], axis=1)
    miss_b = np.linalg.norm(backward - end_hist[a, -1], axis=1)
    tol = params.blend_tolerance_mm * ahead
    ok = (miss_f <= tol) & (miss_b <= tol)
    a, b = a[ok], b[ok]
    if a.size == 0:
        return a, b
    cost = np.full((tracks.n_tracks, tracks.n_tracks), _FAR)
    cost[a, b] = (miss_f + miss_b)[ok]
    ra = np.unique(a)
    cb = np.unique(b)
    r, c = linear_sum_assignment(cost[np.ix_(ra, cb)])
    keep = cost[ra[r], cb[c]] < _FAR
    return ra[r[keep]], cb[c[keep]]


def chain_labels(n_tracks: int, earlier: NDArray, later: NDArray) -> NDArray[np.int64]:
    """Group number per track after joining each ``earlier[i]`` to ``later[i]``."""
    nxt = np.full(n_tracks, -1, dtype=np.int64)
    nxt[earlier] = later
    has_prev = np.zeros(n_tracks, dtype=bool)
    has_prev[later] = True
    group = np.full(n_tracks, -1, dtype=np.int64)
    for g, head in enumerate(np.flatnonzero(~has_prev)):
        t = head
        while t >= 0:
            group[t] = g
            t = nxt[t]
    return group


def blend_tracks(tracks: Tracks, params: TrackingParams) -> Tracks:
    """Connect track pieces whose gap and continuity allow it (Shafiq et al. 2001 §4.3).

    The missing fields of a blended gap are left empty for :func:`fill_gaps`.
    """
    earlier, later = blend_pairs(tracks, params)
    if earlier.size == 0:
        return tracks
    return tracks.renumber(chain_labels(tracks.n_tracks, earlier, later))


def clean_up(tracks: Tracks, params: TrackingParams) -> Tracks:
    """Remove tracks with fewer than ``min_track_length`` measured samples (ghost tracks)."""
    n_measured = tracks.n_status(MEASURED)
    return tracks.select(n_measured[tracks.track] >= params.min_track_length)
