"""Joins judged through the one-sample pieces in their gap (blending's chain cost), and
the fits and extrapolations blending judges joins by.

On fast markers a few centimetres apart (PhaseSpace's hand at 30 Hz: 40-70 mm apart,
moving up to 180 mm a field) the tracker cuts both markers into one-sample pieces where
it cannot tell them apart. A one-sample piece has no velocity of its own: blending never
joins it, and the long pieces either side of the gap were chosen end to end. Judged end
to end, rival joins across such a gap fit one cubic about equally well (a crossed pair
1.9 and 2.9 mm RMS, the true pair 2.2 and 3.3 mm): the cubic need not pass where the
markers were seen. Judged as the whole path, piece before -> the gap's samples -> piece
after (Shafiq et al. 2001's continuity over the chain), they do not: the marker's own
samples continue its path, a neighbour's leave a jump (true paths 8.4 and 10.2 mm RMS,
the crossed ones 11.2 and 13.8 mm).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.predictors import extrapolation_weights, shafiq_rule
from kisscal.tracking.tracks import MEASURED, Tracks

#: Most routes through a gap's samples weighed per join (beyond: judged end to end).
MAX_ROUTES = 256


def bridge_residual_mm(
    fields_a: NDArray, xyz_a: NDArray, fields_b: NDArray, xyz_b: NDArray
) -> float:
    """RMS residual (mm) of one least-squares polynomial through the end of one piece and
    the start of the next: small when both are the same smooth marker path.

    The degree is 3, or lower when few points are given (at least two points are left
    over for the residual).
    """
    f = np.concatenate((fields_a, fields_b)).astype(float)
    x = np.concatenate((xyz_a, xyz_b))
    degree = min(3, f.size - 3)
    if degree < 1:
        return float("inf")
    vander = np.vander(f - f.mean(), degree + 1)
    coef, *_ = np.linalg.lstsq(vander, x, rcond=None)
    return float(np.sqrt(np.mean(np.sum((x - vander @ coef) ** 2, axis=1))))


def extrapolate_gap(history: NDArray, count: NDArray, ahead: NDArray) -> NDArray:
    """Shafiq's extrapolation of each piece's history (nearest last) ``ahead`` fields on;
    one weight vector per (points, fields ahead) combination."""
    out = np.empty((history.shape[0], 3))
    keys = np.stack([np.minimum(count, 5), ahead], axis=1)
    combos, which = np.unique(keys, axis=0, return_inverse=True)
    which = which.ravel()
    for k, (n_points, fields) in enumerate(combos):
        used, degree = shafiq_rule(int(n_points))
        w = extrapolation_weights(used, degree, int(fields))
        rows = which == k
        out[rows] = np.einsum("u,nuc->nc", w, history[rows, -used:])
    return out


def ranges(lo: NDArray, hi: NDArray) -> NDArray[np.int64]:
    """``lo[0]..hi[0]-1, lo[1]..hi[1]-1, ...`` concatenated."""
    size = np.maximum(hi - lo, 0)
    first = np.cumsum(size) - size
    return np.repeat(lo - first, size) + np.arange(int(size.sum()))


def in_fields(tracks: Tracks, rows: NDArray, fields: NDArray) -> tuple[NDArray, NDArray]:
    """The samples of ``rows`` in each of ``fields``: (index into ``fields``, row) pairs."""
    rows = rows[np.argsort(tracks.field[rows], kind="stable")]
    lo = np.searchsorted(tracks.field[rows], fields, "left")
    hi = np.searchsorted(tracks.field[rows], fields, "right")
    return np.repeat(np.arange(len(fields)), hi - lo), rows[ranges(lo, hi)]


def gap_fields(a: NDArray, b: NDArray, ends: tuple[NDArray, ...]) -> tuple[NDArray, ...]:
    """Per field inside the gap of each join ``a[i]`` -> ``b[i]`` (``ends`` as
    :func:`chain_costs`): the join's index, the field, its fields past ``a[i]``'s end, and
    both pieces' extrapolations into it (:func:`extrapolate_gap`)."""
    end_field, end_hist, end_n, _, start_field, start_hist, start_n, _ = ends
    inner = np.maximum(start_field[b] - end_field[a] - 1, 0)
    pair = np.repeat(np.arange(a.size), inner)
    ahead = ranges(np.ones_like(inner), inner + 1)
    ia, ib = a[pair], b[pair]
    gap_field = end_field[ia] + ahead
    fa = extrapolate_gap(end_hist[ia], end_n[ia], ahead)
    fb = extrapolate_gap(start_hist[ib], start_n[ib], start_field[ib] - gap_field)
    return pair, gap_field, ahead, fa, fb


def join_ends(ends: tuple[NDArray, ...], i: int, j: int, k: int) -> tuple[NDArray, ...]:
    """(fields, positions) of the last ``k`` measured samples of piece ``i`` and of the
    first ``k`` of piece ``j`` (``ends`` as :func:`chain_costs`), in field order."""
    _, end_hist, end_n, end_fields, _, start_hist, start_n, start_fields = ends
    n_a, n_b = min(k, end_n[i]), min(k, start_n[j])
    return (
        end_fields[i, 5 - n_a :],
        end_hist[i, 5 - n_a :],
        start_fields[j, 5 - n_b :][::-1],
        start_hist[j, 5 - n_b :][::-1],
    )


def through_gaps(
    earlier: NDArray, later: NDArray, routes: dict[tuple[int, int], NDArray]
) -> tuple[NDArray, NDArray]:
    """The chosen joins ``earlier[i]`` -> ``later[i]`` with the one-sample pieces of the
    path each was judged by (``routes``) joined in between: a gap's sample belongs to the
    marker whose path passes through it. A piece two chosen paths would take joins neither
    (the two joins stand end to end)."""
    paths = [
        routes.get((int(e), int(x)), np.empty(0, dtype=np.int64))
        for e, x in zip(earlier, later, strict=True)
    ]
    used = np.concatenate([np.empty(0, dtype=np.int64), *paths])
    pieces, counts = np.unique(used, return_counts=True)
    shared = pieces[counts > 1]
    pairs = []
    for e, x, path in zip(earlier, later, paths, strict=True):
        chain = [e, *(path if not np.isin(path, shared).any() else ()), x]
        pairs += list(itertools.pairwise(chain))
    out = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    return out[:, 0], out[:, 1]


def chain_costs(
    tracks: Tracks,
    a: NDArray,
    b: NDArray,
    ends: tuple[NDArray, ...],
    k: int,
    reach_mm: float,
) -> tuple[NDArray, list[NDArray]]:
    """Per join ``a[i]`` -> ``b[i]``: the RMS residual (mm) of the smoothest path through
    the samples of one-sample pieces seen in its gap (:func:`chain_residual_mm`), NaN
    where no such sample lies within reach (then the join is judged end to end); and the
    pieces of that path, in field order (empty: none).

    ``ends`` are blending's (end field, end history, end count, end fields, start field,
    start history, start count, start fields) per piece (nearest last, at most 5); ``k``
    the samples used each side (``blend_points``); a gap sample is in reach when within
    ``reach_mm`` per field crossed of both pieces' extrapolations into its field.
    """
    out = np.full(a.size, np.nan)
    routes = [np.empty(0, dtype=np.int64)] * a.size
    pair, gap_field, ahead, fa, fb = gap_fields(a, b, ends)
    if pair.size == 0:
        return out, routes
    counts = tracks.n_status(MEASURED)
    rows = np.flatnonzero((tracks.status == MEASURED) & (counts[tracks.track] == 1))
    q, cand = in_fields(tracks, rows, gap_field)
    x = tracks.xyz_mm[cand]
    near = (np.linalg.norm(x - fa[q], axis=1) <= reach_mm * ahead[q]) & (
        np.linalg.norm(x - fb[q], axis=1) <= reach_mm * (ends[4][b[pair[q]]] - gap_field[q])
    )
    q, cand = q[near], cand[near]
    for i in np.unique(pair[q]):
        mine = pair[q] == i
        options = [cand[mine][q[mine] == g] for g in np.unique(q[mine])]
        if math.prod(o.size for o in options) > MAX_ROUTES:
            continue
        ends_i = join_ends(ends, a[i], b[i], k)
        out[i], route = chain_residual_mm(ends_i, options, tracks.field, tracks.xyz_mm)
        routes[i] = tracks.track[route]
    return out, routes


def chain_residual_mm(
    ends: tuple[NDArray, NDArray, NDArray, NDArray],
    options: list[NDArray],
    field: NDArray,
    xyz: NDArray,
) -> tuple[float, NDArray]:
    """RMS residual (mm) of the smoothest path from one piece's end through one sample of
    each gap field that holds any (``options``: candidate rows per such field) to the
    next piece's start: one least-squares cubic through the chain
    (:func:`bridge_residual_mm`).

    A field whose samples lie within reach is crossed through one of them: the marker was
    seen there, and a path that skips the samples fits a rival join as well as the true
    one. ``ends`` are the (fields, positions) of the earlier piece's last and the later
    piece's first samples. Returns the residual and the rows of the path's samples.
    """
    fa, xa, fb, xb = ends
    best, rows = np.inf, np.empty(0, dtype=np.int64)
    for route in itertools.product(*options):
        r = np.asarray(route, dtype=np.int64)
        residual = bridge_residual_mm(np.r_[fa, field[r]], np.r_[xa, xyz[r]], fb, xb)
        if residual < best:
            best, rows = residual, r
    return best, rows
