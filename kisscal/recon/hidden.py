"""Two markers merged into one blob, placed along their own rays by their trajectories.

Two markers seen by the same two cameras, merged into one blob ``c`` in one camera and
apart (``a``, ``b``) in the other, leave one unknown too many: ``c`` is the area-weighted
mean of the two images (:mod:`kisscal.recon.deblend`), but the epipolar lines of ``a``
and ``b`` meet at a tiny angle in ``c``'s camera, so the blob fixes the sum of the two
markers' positions along those lines and not each (:func:`~kisscal.recon.deblend.
deblend_pairs` refuses such triples). The pair (``c``, ``a``) then reprojects well yet
lands 5-10 mm from either marker, and the other marker is lost.

A rigid segment supplies the missing equation: markers of one segment of the marker set
keep their distance (:class:`~kisscal.recon.body.RigidTriangles`). Where the
constant-velocity predictions ``2 p(f-1) - p(f-2)`` (or from the fields after) of two
trajectories, one of which stops at field f, project within a blob's diameter of each
other in a camera, with a free blob ``c`` (or one a two-camera point holds) at their
mean, each prediction takes the free blob of another camera whose ray passes nearest
(within ``two_camera_continuity_mm``, the gate of a two-camera pair's second difference,
:func:`kisscal.recon.pairs.continuity_mm`), and the segment length nearest to the
predictions' distance (within ``two_camera_body_mm``) is their distance. Both depths
along the own rays then follow by Gauss-Newton from three equations: the weighted mean
of the two images is ``c`` (two) and the distance (one). The fit's RMS residual must lie
within the trial's residual limit, and each marker within ``hidden_prediction_mm`` of
its prediction (a marker beside another's image, not merged with it, fits only when
both are pushed further); each blob serves one solution, best residual first. A two-camera
point that held ``c`` and an own blob moves to its marker's solved position.

The trajectories are followed both ways, one field per round, so a pair merged for a
stretch is found from the fields where it was seen apart. The prediction carries the
trajectory only to the next field: the depths come from the blobs and the segment, save
where the segment lies across the rays of the camera that sees the two apart; there the
length barely changes as the depths trade, and the predictions hold them as a prior.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from kisscal.dlt.model import pixel_size_mm, project_rows, ray_directions, ray_points
from kisscal.recon.deblend import Deblended, MergeScene, depth_of
from kisscal.recon.group import embed_fields, near_cameras

#: Points of the neighbouring field tried as a trajectory's previous position, nearest first.
_NEIGHBOURS = 4


@dataclass(frozen=True)
class Hidden:
    """Hidden markers found (``new``) and the points whose merged blob they share,
    moved to explain it with them (``moved``: point index, ``moved_xyz``)."""

    new: Deblended
    moved: NDArray[np.int64]
    moved_xyz: NDArray[np.float64]


def predictions(
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
    step_mm: float,
    tol_mm: float,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.bool_]]:
    """Constant-velocity predictions ``2 q - p`` of the trajectories through the points,
    into the next and the previous field: ``q`` of field g and ``p`` of field g -/+ 1
    within ``step_mm``, the ``p`` that makes the smoothest window of second difference
    within ``tol_mm`` with a third point of field g -/+ 2, else the nearest. A
    prediction within ``tol_mm`` of one made from the other side is dropped. Returns
    (field, prediction, whether no point of its field lies within ``tol_mm``: the
    trajectory stops there)."""
    ok = np.flatnonzero(np.all(np.isfinite(p_xyz), axis=1))
    none = np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros(0, dtype=bool)
    if len(ok) < 3:
        return none
    xyz, field = p_xyz[ok], p_field[ok]
    tree = cKDTree(embed_fields(xyz, field))
    k = min(_NEIGHBOURS, len(ok))
    at, pred = [], []
    for side in (1, -1):
        d, j = tree.query(embed_fields(xyz, field - side), k=k, distance_upper_bound=step_mm)
        q_row, col = np.nonzero(np.isfinite(d))
        p, q = xyz[j[q_row, col]], xyz[q_row]
        back = tree.query(embed_fields(2.0 * p - q, field[q_row] - 2 * side))[0]
        # a smooth window of three first; a trajectory only two fields long (a marker
        # just come into two cameras' view) from its nearest previous point
        order = np.lexsort((np.where(back <= tol_mm, back, d[q_row, col]), back > tol_mm, q_row))
        first = order[np.r_[True, np.diff(q_row[order]) != 0]] if len(order) else order
        at.append(field[q_row[first]] + side)
        pred.append(2.0 * xyz[q_row[first]] - p[first])
    at_all, pred_all = np.concatenate(at), np.concatenate(pred)
    n_fwd = len(at[0])
    if n_fwd and len(at_all) > n_fwd:  # the same marker predicted from both sides
        twin = cKDTree(embed_fields(pred_all[:n_fwd], at_all[:n_fwd]))
        dup = twin.query(embed_fields(pred_all[n_fwd:], at_all[n_fwd:]))[0] <= tol_mm
        keep = np.r_[np.ones(n_fwd, dtype=bool), ~dup]
        at_all, pred_all = at_all[keep], pred_all[keep]
    stops = tree.query(embed_fields(pred_all, at_all))[0] > tol_mm
    return at_all, pred_all, stops


def deblend_hidden(
    scene: MergeScene,
    marker: NDArray[np.int64],
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
    p_cameras: NDArray[np.int64],
    lengths_mm: NDArray[np.float64],
) -> Hidden:
    """Two markers merged in one blob, placed by their trajectories (see module).

    Parameters
    ----------
    scene : MergeScene
        The trial's 2D table, rig and residual limit; of its ``params``:
        ``two_camera_step_mm``, ``two_camera_continuity_mm``, ``deblend_radius_px``,
        ``two_camera_body_mm``, ``hidden_prediction_mm``, ``group_radius_mm``,
        ``camera_clearance_mm``.
    marker : ndarray of int, shape (n,)
        Point of each blob of the 2D table (-1: unused).
    p_field, p_xyz, p_cameras : ndarray, shapes (m,), (m, 3), (m,)
        The trial's points so far and how many cameras made each.
    lengths_mm : ndarray, shape (k,)
        The marker set's rigid distances (:class:`~kisscal.recon.body.RigidTriangles`):
        the two markers lie one of these apart, the one nearest to their predictions'
        distance and within ``two_camera_body_mm`` of it (none: no pair is placed).

    Returns
    -------
    Hidden
        New points (own blob, the merged blob) and the two-camera points moved.
    """
    params = scene.params
    tol = params.two_camera_continuity_mm
    none = Hidden(Deblended.empty(), np.zeros(0, dtype=np.int64), np.zeros((0, 3)))
    pf, pxyz, stops = predictions(p_field, p_xyz, params.two_camera_step_mm, tol)
    # blobs a hidden pair may use: free ones, and those of two-camera points (remade)
    two = np.r_[p_cameras == 2, False]
    open_ = scene.usable & ((marker < 0) | two[marker])
    P, Q, c = _merged_pairs(scene, open_, pf, pxyz, stops)
    if len(P) == 0:
        return none
    a, da = _own_blobs(scene, open_, c, pf[P], pxyz[P])
    b, db = _own_blobs(scene, open_, c, pf[Q], pxyz[Q])
    ok = (a >= 0) & (b >= 0) & (a != b) & (da <= tol) & (db <= tol)
    ma, mb, mc = marker[a], marker[b], marker[c]
    h = np.maximum(np.maximum(ma, mb), mc)
    # at most one two-camera point among the three blobs, holding c and one own blob
    ok &= ((ma < 0) | (ma == h)) & ((mb < 0) | (mb == h)) & ((mc < 0) | (mc == h))
    held = (ma >= 0).astype(int) + (mb >= 0) + (mc >= 0)
    ok &= (held == 0) | ((held == 2) & (mc >= 0))
    holder = np.where(held == 2, h, -1)
    gap = np.linalg.norm(pxyz[P] - pxyz[Q], axis=1)
    want, off = nearest_length(gap, lengths_mm)
    ok &= off <= params.two_camera_body_mm
    P, Q, c, a, b, holder, want = (v[ok] for v in (P, Q, c, a, b, holder, want))
    xa, xb, resid = solve_pair(scene, c, a, b, pxyz[P], pxyz[Q], want)
    good = resid <= scene.limit_px
    near = params.hidden_prediction_mm
    good &= np.linalg.norm(xa - pxyz[P], axis=1) <= near
    good &= np.linalg.norm(xb - pxyz[Q], axis=1) <= near
    good &= np.linalg.norm(xa - xb, axis=1) >= params.group_radius_mm
    good &= ~near_cameras(np.nan_to_num(xa), scene.dlts, params.camera_clearance_mm)
    good &= ~near_cameras(np.nan_to_num(xb), scene.dlts, params.camera_clearance_mm)
    idx = np.flatnonzero(good)
    idx = idx[_disjoint3(a[idx], b[idx], c[idx], resid[idx], len(scene.field))]
    return _outcome(
        marker, c[idx], a[idx], b[idx], holder[idx], xa[idx], xb[idx], resid[idx], scene.field
    )


def _merged_pairs(
    scene: MergeScene,
    open_: NDArray[np.bool_],
    pf: NDArray[np.int64],
    pxyz: NDArray[np.float64],
    stops: NDArray[np.bool_],
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """(prediction, prediction, blob): two predictions of one field, one of them a
    trajectory that stops, whose images in a camera lie within twice
    ``deblend_radius_px`` of each other, and the open blob nearest to their mean there
    (within ``deblend_radius_px``)."""
    field, camera, uv, dlts = scene.field, scene.camera, scene.uv, scene.dlts
    r = scene.params.deblend_radius_px
    out = []
    for j in range(len(dlts)):
        rows = np.flatnonzero(open_ & (camera == j))
        if len(rows) == 0 or len(pf) < 2:
            continue
        img = project_rows(dlts, np.full(len(pf), j), pxyz)
        front = (depth_of(dlts, np.full(len(pf), j), pxyz) > 0) & np.all(np.isfinite(img), axis=1)
        ids = np.flatnonzero(front)
        pairs = cKDTree(embed_fields(img[ids], pf[ids])).query_pairs(2.0 * r, output_type="ndarray")
        if len(pairs) == 0:
            continue
        P, Q = ids[pairs[:, 0]], ids[pairs[:, 1]]
        keep = stops[P] | stops[Q]
        P, Q = P[keep], Q[keep]
        d, near = cKDTree(embed_fields(uv[rows], field[rows])).query(
            embed_fields(0.5 * (img[P] + img[Q]), pf[P]), distance_upper_bound=r
        )
        hit = np.isfinite(d)
        out.append(np.column_stack([P[hit], Q[hit], rows[near[hit]]]))
    if not out:
        e = np.zeros(0, dtype=np.int64)
        return e, e, e
    got = np.concatenate(out)
    return got[:, 0], got[:, 1], got[:, 2]


def _own_blobs(
    scene: MergeScene,
    open_: NDArray[np.bool_],
    c: NDArray[np.int64],
    f: NDArray[np.int64],
    x: NDArray[np.float64],
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Per prediction ``x`` of field ``f``: the open blob of a camera other than blob
    ``c``'s whose ray passes nearest to it (by image distance per camera), and that
    ray's 3D distance (mm; inf and -1 when none)."""
    field, camera, uv, dlts = scene.field, scene.camera, scene.uv, scene.dlts
    best = np.full(len(c), -1, dtype=np.int64)
    dist = np.full(len(c), np.inf)
    for k in range(len(dlts)):
        rows = np.flatnonzero(open_ & (camera == k))
        sel = np.flatnonzero(camera[c] != k)
        if len(rows) == 0 or len(sel) == 0:
            continue
        img = np.nan_to_num(project_rows(dlts, np.full(len(sel), k), x[sel]))
        _, near = cKDTree(embed_fields(uv[rows], field[rows])).query(embed_fields(img, f[sel]))
        blob = rows[near]
        same = field[blob] == f[sel]
        on_ray = ray_points(dlts, camera[blob], uv[blob], x[sel])
        d = np.where(same, np.linalg.norm(on_ray - x[sel], axis=1), np.inf)
        better = d < dist[sel]
        best[sel[better]], dist[sel[better]] = blob[better], d[better]
    return best, dist


def solve_pair(
    scene: MergeScene,
    c: NDArray[np.int64],
    a: NDArray[np.int64],
    b: NDArray[np.int64],
    pa: NDArray[np.float64],
    pb: NDArray[np.float64],
    want: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Both markers on their own blobs' rays (depths ``s``): the area-weighted mean of
    their images is blob ``c`` and they lie ``want`` (mm, a rigid segment) apart, by
    Gauss-Newton from the predictions ``pa``, ``pb``. Returns both points and the RMS
    residual (px; the distance error in pixels at the markers) of those three equations.

    The blob and the length leave a valley, nearly flat when the segment lies across the
    rays, along which the two depths trade: image noise moves its floor by many
    millimetres. The predictions settle it, as a prior (Kalman's update): each depth's
    offset from its prediction counts as an image residual of ``s / hidden_prediction_mm``
    residual limits, so the fit keeps to them along the valley and to the blob across it.
    """
    camera, uv, dlts = scene.camera, scene.uv, scene.dlts
    j = camera[c]
    a0, ua = _ray(dlts, camera[a], uv[a], pa)
    b0, ub = _ray(dlts, camera[b], uv[b], pb)
    px_mm = pixel_size_mm(dlts, j, np.nan_to_num(pa))
    prior = scene.limit_px / scene.params.hidden_prediction_mm

    def resid(s: NDArray[np.float64]) -> NDArray[np.float64]:
        xa, xb = a0 + s[:, :1] * ua, b0 + s[:, 1:] * ub
        wa = 1.0 / np.maximum(depth_of(dlts, j, xa) ** 2, 1e-18)  # area falls with depth²
        wb = 1.0 / np.maximum(depth_of(dlts, j, xb) ** 2, 1e-18)
        img = wa[:, None] * project_rows(dlts, j, xa) + wb[:, None] * project_rows(dlts, j, xb)
        cen = img / (wa + wb)[:, None] - uv[c]
        length = (np.linalg.norm(xa - xb, axis=1) - want) / px_mm
        return np.column_stack([cen, length, prior * s])

    s = np.zeros((len(c), 2))
    cost = _cost(resid(s))
    for _ in range(_GAUSS_NEWTON):
        r0 = resid(s)
        jac = np.stack([(resid(s + e) - r0) / _STEP_MM for e in np.eye(2) * _STEP_MM], axis=2)
        g = np.einsum("nki,nkj->nij", jac, jac) + 1e-9 * np.eye(2)
        step = np.linalg.solve(g, np.einsum("nki,nk->ni", jac, r0)[..., None])[..., 0]
        s, cost = _backtrack(resid, s, step, cost)
    r = resid(s)[:, :3]
    ok = np.all(np.isfinite(r), axis=1)
    rms = np.where(ok, np.sqrt(np.mean(np.nan_to_num(r) ** 2, axis=1)), np.inf)
    return a0 + s[:, :1] * ua, b0 + s[:, 1:] * ub, rms


def _cost(r: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sum of squared residuals per row (inf where one is not finite)."""
    c = np.sum(r**2, axis=1)
    return np.where(np.isfinite(c), c, np.inf)


def _backtrack(
    resid: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    s: NDArray[np.float64],
    step: NDArray[np.float64],
    cost: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``s - t step`` for the largest ``t`` of 1, 1/2, 1/4, ... that lowers the cost, per
    row (``s`` kept where none does), and its cost. The blob and the length leave a flat
    valley along which the two depths trade: a full Gauss-Newton step overshoots across
    it, and undamped steps went on oscillating 10 mm along it (Nocedal & Wright 2006,
    backtracking line search)."""
    s, cost, done = s.copy(), cost.copy(), np.zeros(len(s), dtype=bool)
    for k in range(_HALVINGS):
        trial = s - step * 0.5**k
        c = _cost(resid(trial))
        take = ~done & (c < cost)
        s[take], cost[take], done = trial[take], c[take], done | take
    return s, cost


def nearest_length(
    gap: NDArray[np.float64], lengths: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The length nearest to each ``gap`` and how far (inf when there is none)."""
    if len(lengths) == 0:
        return np.full(len(gap), np.nan), np.full(len(gap), np.inf)
    lengths = np.sort(lengths)
    i = np.clip(np.searchsorted(lengths, gap), 1, max(len(lengths) - 1, 1))
    lo, hi = lengths[i - 1], lengths[np.minimum(i, len(lengths) - 1)]
    best = np.where(np.abs(gap - lo) <= np.abs(gap - hi), lo, hi)
    return best, np.abs(gap - best)


def _ray(
    dlts: NDArray[np.float64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    target: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The ray of each blob: its point nearest ``target`` and its unit direction."""
    return ray_points(dlts, camera, uv, target), ray_directions(dlts[camera], uv)


def _disjoint3(
    a: NDArray[np.int64], b: NDArray[np.int64], c: NDArray[np.int64], score, n: int
) -> NDArray[np.int64]:
    """Indices of candidates taken best ``score`` first so that each blob of ``a``, ``b``,
    ``c`` serves one (rounds: every candidate first at all its blobs is taken)."""
    rank = np.empty(len(a), dtype=np.int64)
    rank[np.lexsort((np.arange(len(a)), score))] = np.arange(len(a))
    alive = np.ones(len(a), dtype=bool)
    taken = np.zeros(len(a), dtype=bool)
    while alive.any():
        k = np.flatnonzero(alive)
        first = np.full(n, len(a), dtype=np.int64)
        for blob in (a, b, c):
            np.minimum.at(first, blob[k], rank[k])
        won = k[(first[a[k]] == rank[k]) & (first[b[k]] == rank[k]) & (first[c[k]] == rank[k])]
        taken[won] = True
        used = np.zeros(n, dtype=bool)
        used[a[won]] = used[b[won]] = used[c[won]] = True
        alive &= ~used[a] & ~used[b] & ~used[c]
    return np.flatnonzero(taken)


def _outcome(
    marker: NDArray[np.int64],
    c: NDArray[np.int64],
    a: NDArray[np.int64],
    b: NDArray[np.int64],
    holder: NDArray[np.int64],
    xa: NDArray[np.float64],
    xb: NDArray[np.float64],
    rms: NDArray[np.float64],
    field: NDArray[np.int64],
) -> Hidden:
    """New points and moved holders: a two-camera point holding ``c`` and one own blob
    moves to that marker's position, the other marker is new; with no holder both are."""
    moves_a = (holder >= 0) & (marker[a] == holder)
    moves_b = (holder >= 0) & (marker[b] == holder)
    new_a, new_b = ~moves_a, ~moves_b
    own = np.r_[a[new_a], b[new_b]]
    xyz = np.r_[xa[new_a], xb[new_b]]
    merged = np.r_[c[new_a], c[new_b]]
    new = Deblended(xyz, field[own], np.r_[rms[new_a], rms[new_b]], own, merged)
    moved = np.r_[holder[moves_a], holder[moves_b]]
    return Hidden(new, moved, np.r_[xa[moves_a], xb[moves_b]])


#: Gauss-Newton steps of :func:`solve_pair`, halvings of a step that does not lower the
#: cost (:func:`_backtrack`) and the finite-difference step (mm).
_GAUSS_NEWTON = 10
_HALVINGS = 6
_STEP_MM = 0.05
