"""Two-camera points that share a blob: a marker whose image merged with another's.

When two markers project within a blob's size of each other in one camera, that camera
gives one blob for both, and the blob goes to the marker that other cameras confirm. A
marker that only one further camera sees then has one blob of its own: it cannot be
triangulated from its own blobs, and multi-camera matching, which uses each blob once,
leaves it out (issue 27: most of the misses of markers seen by exactly two cameras on a
four-camera rig).

Such a marker is put back where three facts agree:

* its own blob ``b`` (unused) and a blob ``a`` of another camera (used or not) lie in
  each other's epipolar bands;
* the rough point of that pair continues a trajectory of the trial's points
  (:func:`~kisscal.recon.pairs.continuity_mm`'s four-field windows), and the three other
  positions of that window predict the marker's position in the field (constant
  acceleration through them, as a tracker's prediction; Küçük 2005, 3.4);
* the point of ``b``'s ray nearest to that prediction lies within ``group_radius_mm`` of
  it, projects within ``search_radius_px`` of ``a`` and is not a point the field has.

The point is that nearest point of ``b``'s ray (the shared blob ``a`` lies up to a blob's
radius off the marker's image, so triangulating through it would be off by as much), or,
when ``a`` is unused and the pair reprojects within the trial's residual limit, the pair's
triangulation. Rounds repeat with the new points in the pool, so that a marker merged
for several fields in a row is followed field by field from both ends.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from kisscal.dlt.model import project_rows
from kisscal.dlt.triangulate import triangulate_observations
from kisscal.recon.epipolar import candidate_pairs
from kisscal.recon.group import first_per_key, near_cameras
from kisscal.recon.pairs import _continuity, _embed, _Part, _Pool
from kisscal.recon.params import ReconParams

#: Rounds of the search (each may follow a merged stretch one field further from each end).
ROUNDS = 30
ANCHOR_NEW = True


@dataclass(frozen=True)
class SharedPoints:
    """Points made with a shared blob: ``field`` (n,), ``xyz_mm`` (n, 3), ``rows`` (n, 2):
    the marker's own blob and its partner (the partner may belong to another point too),
    ``rms_px`` (n,) and ``own_partner`` (n,): whether the partner is the point's alone."""

    field: NDArray[np.int64]
    xyz_mm: NDArray[np.float64]
    rows: NDArray[np.int64]
    rms_px: NDArray[np.float64]
    own_partner: NDArray[np.bool_]


def _empty() -> SharedPoints:
    z = np.zeros(0, dtype=np.int64)
    return SharedPoints(z, np.zeros((0, 3)), z.reshape(0, 2), np.zeros(0), z > 0)


def _quadratic_at(
    xyz: NDArray[np.float64], at: NDArray[np.float64], f: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Position at field ``f`` (n,) of the parabola through three positions ``xyz`` (n, 3,
    3) of fields ``at`` (n, 3), all distinct (Lagrange's form)."""
    w = np.ones(at.shape)
    for i in range(3):
        for j in range(3):
            if i != j:
                w[:, i] *= (f - at[:, j]) / (at[:, i] - at[:, j])
    return np.einsum("ni,nik->nk", w, xyz)


def _nearest_on_ray(
    L: NDArray[np.float64], uv: NDArray[np.float64], p: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The point of each blob's ray (DLT rows ``L`` (n, 11), pixel ``uv`` (n, 2)) nearest
    to ``p`` (n, 3): the ray is the two planes ``A x = c`` of the DLT equations, and the
    nearest point ``p + A^T (A A^T)^-1 (c - A p)``."""
    lower = L[:, 8:11]
    A = np.stack([L[:, 0:3] - uv[:, :1] * lower, L[:, 4:7] - uv[:, 1:] * lower], axis=1)
    c = np.stack([uv[:, 0] - L[:, 3], uv[:, 1] - L[:, 7]], axis=1)
    r = c - np.einsum("nij,nj->ni", A, p)
    lam = np.linalg.solve(A @ A.transpose(0, 2, 1), r[..., None])[..., 0]
    return p + np.einsum("nij,ni->nj", A, lam)


def _verified(
    xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    strong: NDArray[np.bool_],
    params: ReconParams,
) -> NDArray[np.bool_]:
    """Points on a trajectory that holds a ``strong`` point (one that three or more cameras
    see): the points joined by :func:`~kisscal.recon.pairs.continuity_mm`'s windows, in
    connected pieces. A ghost of two markers' rays crossing can move smoothly for a while
    (the two markers move together), but no third camera confirms it anywhere."""
    ids = np.arange(len(field))
    pool = _Pool([_Part(xyz, field, ids)], params.two_camera_continuity_mm)
    _, win = _continuity(xyz, field, pool, params.two_camera_step_mm)
    win = win[np.all(win >= 0, axis=1)]
    src = np.repeat(win[:, 0], 3)
    n = len(field)
    graph = coo_matrix((np.ones(len(src)), (src, win[:, 1:].ravel())), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    held = np.zeros(label.max(initial=0) + 1, dtype=bool)
    held[label[strong]] = True
    return held[label]


def _candidates(
    free: NDArray[np.bool_],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    F: NDArray[np.float64],
    params: ReconParams,
    usable: NDArray[np.bool_],
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Epipolar pairs among the ``usable`` blobs with at least one ``free`` blob, oriented
    (own blob ``b`` free, partner ``a``); a pair of two free blobs is tried both ways."""
    rows = np.flatnonzero(usable)
    i, j, _ = candidate_pairs(field[rows], camera[rows], uv[rows], F, params.epipolar_band_px)
    i, j = rows[i], rows[j]
    b = np.concatenate([i[free[i]], j[free[j]]])
    a = np.concatenate([j[free[i]], i[free[j]]])
    return b, a


def _judge(
    b: NDArray[np.int64],
    a: NDArray[np.int64],
    pool: tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.bool_]],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    params: ReconParams,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """The candidate pairs that continue a trajectory of the ``pool`` (points, fields):
    per window found, the candidate, the point on ``b``'s ray nearest the window's
    prediction and its distance to it (mm)."""
    pool_xyz, pool_field, anchor = pool
    t = triangulate_observations(
        dlts,
        np.repeat(np.arange(len(b)), 2),
        np.column_stack([camera[b], camera[a]]).ravel(),
        np.stack([uv[b], uv[a]], axis=1).reshape(-1, 2),
        len(b),
        0,
    )
    # the rough point is off by up to a blob's radius at the shared blob's distance:
    # windows are searched with room for that, the prediction then decides
    tol = 3.0 * params.two_camera_continuity_mm
    part = _Part(pool_xyz, pool_field, np.arange(len(pool_field)))
    step = params.two_camera_step_mm
    _, win = _continuity(t.xyz_mm, field[b], _Pool([part], tol), step, np.r_[anchor, False])
    k = win[:, 0]
    ok = np.all(win[:, 1:] >= 0, axis=1)
    win, k = win[ok], k[ok]
    pred = _quadratic_at(
        pool_xyz[win[:, 1:]], pool_field[win[:, 1:]].astype(float), field[b[k]].astype(float)
    )
    x = _nearest_on_ray(dlts[camera[b[k]]], uv[b[k]], pred)
    return k, x, np.linalg.norm(x - pred, axis=1)


def shared_blob_points(
    marker: NDArray[np.int64],
    usable: NDArray[np.bool_],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    points: tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.bool_]],
    F: NDArray[np.float64],
    params: ReconParams,
    limit_px: float,
) -> SharedPoints:
    """Two-camera points of markers whose blob merged with another's in one camera (see
    module docstring).

    Parameters
    ----------
    marker : ndarray of int, shape (n,)
        Point of each blob of the trial's 2D table (-1: unused).
    usable : ndarray of bool, shape (n,)
        Blobs that may take part (not stationary, not at an epipole).
    field, camera, uv : ndarray
        The 2D table (linearised px).
    dlts : ndarray, shape (n_cameras, 11)
    points : tuple of ndarray
        The trial's points (n_points, 3) and their fields: the trajectories.
    F : ndarray
        :func:`~kisscal.recon.epipolar.all_fundamentals` of ``dlts``.
    params : ReconParams
        ``epipolar_band_px``, ``search_radius_px``, ``group_radius_mm``,
        ``two_camera_step_mm``, ``two_camera_continuity_mm``, ``camera_clearance_mm``.
    limit_px : float
        The trial's residual limit: a pair of two unused blobs within it is triangulated.

    Returns
    -------
    SharedPoints
    """
    free = (marker < 0) & usable
    pool_xyz, pool_field, strong = points
    anchor = strong.copy()
    found = [_empty()]
    b_all, a_all = _candidates(free, field, camera, uv, F, params, usable)
    for _ in range(ROUNDS):
        b, a = b_all[free[b_all]], a_all[free[b_all]]
        if len(b) == 0:
            break
        pool = (pool_xyz, pool_field, anchor)
        k, x, gap = _judge(b, a, pool, field, camera, uv, dlts, params)
        new = _accept(b[k], a[k], x, gap, (pool_xyz, pool_field), field, camera, uv, dlts, params)
        new = _finish(*new, free, field, camera, uv, dlts, params, limit_px)
        if len(new.field) == 0:
            break
        found.append(new)
        free[new.rows[:, 0]] = False
        free[new.rows[new.own_partner, 1]] = False
        pool_xyz = np.concatenate([pool_xyz, new.xyz_mm])
        pool_field = np.concatenate([pool_field, new.field])
        anchor = np.r_[anchor, np.full(len(new.field), ANCHOR_NEW)]
    return SharedPoints(
        *(np.concatenate([getattr(s, n) for s in found]) for n in SharedPoints.__annotations__)
    )


def _accept(
    b: NDArray[np.int64],
    a: NDArray[np.int64],
    x: NDArray[np.float64],
    gap: NDArray[np.float64],
    pool: tuple[NDArray[np.float64], NDArray[np.int64]],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    params: ReconParams,
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """The judged candidates that become points: near their prediction, near their
    partner's blob, not a point the field has, one per own blob and per place."""
    d = np.linalg.norm(project_rows(dlts, camera[a], x) - uv[a], axis=1)
    ok = (gap <= params.group_radius_mm) & (d <= params.search_radius_px)
    ok &= ~near_cameras(x, dlts, params.camera_clearance_mm)
    b, a, x, gap = b[ok], a[ok], x[ok], gap[ok]
    pool_xyz, pool_field = pool
    fin = np.all(np.isfinite(pool_xyz), axis=1)
    if len(b) and fin.any():
        tree = cKDTree(_embed(pool_xyz[fin], pool_field[fin]))
        taken = tree.query(_embed(x, field[b]), distance_upper_bound=params.group_radius_mm)[0]
        keep = ~np.isfinite(taken)
        b, a, x, gap = b[keep], a[keep], x[keep], gap[keep]
    keep = first_per_key(b, gap)  # the best window of each own blob
    b, a, x, gap = b[keep], a[keep], x[keep], gap[keep]
    if len(b) > 1:  # two own blobs (two cameras) of one marker: the better one
        close = cKDTree(_embed(x, field[b])).query_pairs(
            params.group_radius_mm, output_type="ndarray"
        )
        i, j = close[:, 0], close[:, 1]
        worse = np.where(gap[i] <= gap[j], j, i)
        keep = np.ones(len(b), dtype=bool)
        keep[worse] = False
        b, a, x = b[keep], a[keep], x[keep]
    return b, a, x


def _finish(
    b: NDArray[np.int64],
    a: NDArray[np.int64],
    x: NDArray[np.float64],
    free: NDArray[np.bool_],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    params: ReconParams,
    limit_px: float,
) -> SharedPoints:
    """The accepted points with their residuals; a partner that is unused, no point's own
    blob and the pair's within the residual limit becomes the point's own, and the pair's
    triangulation its position."""
    mine = free[a] & ~np.isin(a, b)
    t = triangulate_observations(
        dlts,
        np.repeat(np.arange(len(b)), 2),
        np.column_stack([camera[b], camera[a]]).ravel(),
        np.stack([uv[b], uv[a]], axis=1).reshape(-1, 2),
        len(b),
        params.reweight_iterations,
    )
    mine &= t.rms_px <= limit_px
    idx = np.flatnonzero(mine)
    mine[:] = False
    mine[idx[first_per_key(a[idx], t.rms_px[idx])]] = True
    x = np.where(mine[:, None], t.xyz_mm, x)
    res = [project_rows(dlts, camera[r], x) - uv[r] for r in (b, a)]
    rms = np.sqrt(0.5 * sum(np.sum(e * e, axis=1) for e in res))
    return SharedPoints(field[b], x, np.column_stack([b, a]), rms, mine)
