"""Markers hidden in another marker's blob: one blob serving two 3D points.

When two markers' images overlap in one camera the detector returns one blob for both,
at the intensity centroid of the union: for equal spherical markers the mean of the two
images weighted by their areas, which fall with the square of the depth,
``c = (w_a p_a + w_b p_b) / (w_a + w_b)``, ``w = 1 / depth^2``. If marker A is known
(found by other cameras, or from its own pair) its image ``p_a`` there is its projection,
and the other marker's image follows from the blob, ``p_b = (c (w_a + w_b) - w_a p_a) /
w_b``: the blob is deblended. A blob of B's own in a second camera whose epipolar line
passes through ``p_b`` then makes B's point, from two cameras.

Such a point has no third view to confirm it, so it faces the checks of every two-camera
point (:mod:`kisscal.recon.pairs`): the trial's residual limit, continuity of a trajectory
and the contest for blobs. A marker merged with a neighbour for a whole stretch is found
field by field as its trajectory is extended from the fields where it was seen apart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from kisscal.dlt.model import project_rows
from kisscal.dlt.triangulate import triangulate_observations
from kisscal.recon.body import RigidTriangles, body_error
from kisscal.recon.epipolar import (
    all_fundamentals,
    candidate_pairs,
    epipolar_lines,
    pair_distances_px,
)
from kisscal.recon.group import embed_fields, near_cameras
from kisscal.recon.pairs import choose_pairs, continuity_mm
from kisscal.recon.params import ReconParams


@dataclass(frozen=True)
class Deblended:
    """Two-camera points made with a deblended blob.

    ``xyz_mm`` (n, 3), ``field`` (n,), ``rms_px`` (n,); ``own_row`` (n,) the point's own
    blob and ``merged_row`` (n,) the blob it shares with another point (rows of the 2D
    table).
    """

    xyz_mm: NDArray[np.float64]
    field: NDArray[np.int64]
    rms_px: NDArray[np.float64]
    own_row: NDArray[np.int64]
    merged_row: NDArray[np.int64]

    @classmethod
    def empty(cls) -> Deblended:
        """No point."""
        none = np.zeros(0, dtype=np.int64)
        return cls(np.zeros((0, 3)), none, np.zeros(0), none, none)


@dataclass(frozen=True)
class MergeScene:
    """What deblending reads of a trial: its 2D table (``field``, ``camera``, ``uv`` in
    linearised px; ``usable``: blobs that may be a marker's, not stationary false
    detections), the rig's ``dlts`` (n_cameras, 11), the settings, and ``limit_px``, the
    largest reprojection ``rms_px`` of a new point (the trial's residual limit)."""

    field: NDArray[np.int64]
    camera: NDArray[np.int64]
    uv: NDArray[np.float64]
    usable: NDArray[np.bool_]
    dlts: NDArray[np.float64]
    params: ReconParams
    limit_px: float


def depth_of(dlts: NDArray[np.float64], camera: NDArray[np.int64], xyz: NDArray[np.float64]):
    """DLT denominators ``L9 X + L10 Y + L11 Z + 1`` (proportional to depth)."""
    return np.einsum("ij,ij->i", dlts[camera, 8:11], xyz) + 1.0


def near_blobs(
    scene: MergeScene, p_field: NDArray[np.int64], p_xyz: NDArray[np.float64], candidate: NDArray
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    """(point, blob, point's projection) for every ``candidate`` blob of the ``scene``
    within its ``params.deblend_radius_px`` of a point's projection into the blob's
    camera, in the point's field."""
    out_p, out_b, out_uv = [], [], []
    dlts, field, uv = scene.dlts, scene.field, scene.uv
    for j in range(len(dlts)):
        rows = np.flatnonzero(candidate & (scene.camera == j))
        if len(rows) == 0 or len(p_xyz) == 0:
            continue
        proj = project_rows(dlts, np.full(len(p_xyz), j), p_xyz)
        front = depth_of(dlts, np.full(len(p_xyz), j), p_xyz) > 0
        pts = np.flatnonzero(front & np.all(np.isfinite(proj), axis=1))
        tree = cKDTree(embed_fields(uv[rows], field[rows]))
        hits = tree.query_ball_point(
            embed_fields(proj[pts], p_field[pts]), scene.params.deblend_radius_px
        )
        n_hits = np.fromiter((len(h) for h in hits), dtype=np.int64, count=len(hits))
        if n_hits.sum() == 0:
            continue
        out_p.append(np.repeat(pts, n_hits))
        out_b.append(rows[np.concatenate([np.asarray(h, dtype=np.int64) for h in hits])])
        out_uv.append(np.repeat(proj[pts], n_hits, axis=0))
    if not out_p:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros((0, 2))
    return np.concatenate(out_p), np.concatenate(out_b), np.concatenate(out_uv)


def _partners(
    blob: NDArray[np.int64],
    image: NDArray[np.float64],
    free: NDArray[np.int64],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    F: NDArray[np.float64],
    band_px: float,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(candidate, free blob) pairs: free blobs of another camera in the candidate's field
    whose epipolar band holds the deblended ``image`` and vice versa."""
    order = np.argsort(field[free], kind="stable")
    free = free[order]
    lo = np.searchsorted(field[free], field[blob], side="left")
    hi = np.searchsorted(field[free], field[blob], side="right")
    n = hi - lo
    k = np.repeat(np.arange(len(blob)), n)
    start = np.repeat(lo - np.cumsum(n) + n, n)
    u = free[start + np.arange(n.sum())]
    ok = camera[u] != camera[blob[k]]
    k, u = k[ok], u[ok]
    d = np.full(len(k), np.inf)
    for ci in np.unique(camera[blob[k]]):
        for cu in np.unique(camera[u]):
            s = (camera[blob[k]] == ci) & (camera[u] == cu)
            if s.any():
                d[s] = np.maximum(*pair_distances_px(F[ci, cu], image[k[s]], uv[u[s]]))
    keep = d < band_px
    return k[keep], u[keep]


def solve_deblended(
    dlts: NDArray[np.float64],
    cams: NDArray[np.int64],
    own_uv: NDArray[np.float64],
    c_uv: NDArray[np.float64],
    known_uv: NDArray[np.float64],
    w_known: NDArray[np.float64],
    iterations: int,
    reweight: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Triangulate the hidden markers from their own blob (camera ``cams[:, 0]``) and the
    deblended image in the merged blob's camera ``cams[:, 1]``, the weights updated from
    the estimate's depth ``iterations`` times. Returns xyz, rms, deblended image."""
    n = len(own_uv)
    w_own = w_known.copy()  # equal weights first: the two at a similar depth
    for _ in range(iterations + 1):
        image = (c_uv * (w_known + w_own)[:, None] - w_known[:, None] * known_uv) / w_own[:, None]
        t = triangulate_observations(
            dlts,
            np.repeat(np.arange(n), 2),
            cams.ravel(),
            np.stack([own_uv, image], axis=1).reshape(-1, 2),
            n,
            reweight,
        )
        depth = depth_of(dlts, cams[:, 1], np.nan_to_num(t.xyz_mm))
        w_own = np.where(np.abs(depth) > 0, 1.0 / np.maximum(depth * depth, 1e-18), w_known)
    return t.xyz_mm, t.rms_px, image


def deblend_merged(
    scene: MergeScene,
    marker: NDArray[np.int64],
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
) -> Deblended:
    """Two-camera points of markers whose image merged with a known point's (see module).

    Parameters
    ----------
    scene : MergeScene
        The trial's 2D table, rig and residual limit. Of its ``params``:
        ``deblend_radius_px`` (how far a known point's projection may lie from the blob it
        shares), ``epipolar_band_px``, ``group_radius_mm`` (a new point lies at least
        this far from the points of its field), ``camera_clearance_mm``, the two-camera
        continuity settings and ``reweight_iterations``.
    marker : ndarray of int, shape (n,)
        Point of each blob of the 2D table (-1: unused).
    p_field, p_xyz : ndarray, shapes (m,), (m, 3)
        The trial's points so far.

    Returns
    -------
    Deblended
        The new points, at most one per own blob, in no particular order.
    """
    field, camera, uv, usable = scene.field, scene.camera, scene.uv, scene.usable
    dlts, params, limit_px = scene.dlts, scene.params, scene.limit_px
    empty = Deblended.empty()
    free = np.flatnonzero((marker < 0) & usable)
    P, c, p_a = near_blobs(scene, p_field, p_xyz, usable)
    mine = (marker[c] < 0) | (marker[c] == P)
    P, c, p_a = P[mine], c[mine], p_a[mine]
    p_a = _projection_without(P, c, marker, camera, uv, dlts, p_a, params.reweight_iterations)
    # a blob within the residual limit of the point's projection is the point's alone
    mine = np.linalg.norm(uv[c] - p_a, axis=1) > limit_px
    P, c, p_a = P[mine], c[mine], p_a[mine]
    if len(P) == 0 or len(free) == 0:
        return empty
    F = all_fundamentals(dlts)
    k, u = _partners(c, 2.0 * uv[c] - p_a, free, field, camera, uv, F, params.epipolar_band_px)
    if len(k) == 0:
        return empty
    cams = np.column_stack([camera[u], camera[c[k]]])
    depth = depth_of(dlts, cams[:, 1], p_xyz[P[k]])
    xyz, rms, image = solve_deblended(
        dlts, cams, uv[u], uv[c[k]], p_a[k], 1.0 / depth**2, 2, params.reweight_iterations
    )
    good = np.all(np.isfinite(xyz), axis=1) & (rms <= limit_px)
    good &= np.linalg.norm(image - uv[c[k]], axis=1) <= 2.0 * params.deblend_radius_px
    good &= ~near_cameras(xyz, dlts, params.camera_clearance_mm)
    good[good] &= apart(xyz[good], field[u[good]], p_xyz, p_field, params.group_radius_mm)
    k, u, xyz, rms = k[good], u[good], xyz[good], rms[good]
    if len(k) == 0:
        return empty
    virtual = len(field) + k  # one deblended image per (point, blob)
    won = choose_pairs(u, virtual, xyz, field[u], p_xyz, p_field, params, True, alone=True)
    return Deblended(xyz[won], field[u[won]], rms[won], u[won], c[k[won]])


def _projection_without(
    P: NDArray[np.int64],
    c: NDArray[np.int64],
    marker: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    p_a: NDArray[np.float64],
    reweight: int,
) -> NDArray[np.float64]:
    """Projections ``p_a`` of points ``P`` into blob ``c``'s camera, for the points that
    hold ``c`` and two more blobs recomputed without ``c``: a merged blob within the
    residual limit pulls the point towards itself."""
    out = p_a.copy()
    rows = np.flatnonzero(marker >= 0)
    rows = rows[np.argsort(marker[rows], kind="stable")]
    lo = np.searchsorted(marker[rows], P, side="left")
    n = np.searchsorted(marker[rows], P, side="right") - lo
    sel = np.flatnonzero((marker[c] == P) & (n >= 3))
    if len(sel) == 0:
        return out
    k = np.repeat(sel, n[sel])
    obs = rows[np.repeat(lo[sel] - np.cumsum(n[sel]) + n[sel], n[sel]) + np.arange(n[sel].sum())]
    keep = obs != c[k]
    k, obs = k[keep], obs[keep]
    idx = np.searchsorted(sel, k)
    t = triangulate_observations(dlts, idx, camera[obs], uv[obs], len(sel), reweight)
    ok = np.all(np.isfinite(t.xyz_mm), axis=1)
    out[sel[ok]] = project_rows(dlts, camera[c[sel[ok]]], t.xyz_mm[ok])
    return out


def apart(
    xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
    p_field: NDArray[np.int64],
    radius_mm: float,
) -> NDArray[np.bool_]:
    """Points at least ``radius_mm`` from every point of their field (not a copy)."""
    ok = np.all(np.isfinite(p_xyz), axis=1)
    if not ok.any():
        return np.ones(len(xyz), dtype=bool)
    tree = cKDTree(embed_fields(p_xyz[ok], p_field[ok]))
    return tree.query(embed_fields(xyz, field))[0] >= radius_mm


def deblend_pairs(
    scene: MergeScene,
    marker: NDArray[np.int64],
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
) -> Deblended:
    """Two markers each seen by two cameras, merged into one free blob ``c`` in a third
    view: each has a free blob of its own elsewhere (``a``, ``b``). Their images in
    ``c``'s camera lie on the epipolar lines of ``a`` and ``b`` and average (weighted by
    area) to ``c``, which places both (the intersection of one line with the other
    reflected through ``c``); the images must lie more than twice the residual limit
    ``scene.limit_px`` apart (else the blob is one marker's). Nothing is left over to check the
    solution: both points must continue trajectories through the points of the trial
    (``p_field``, ``p_xyz``), and both win their blobs, or neither is made."""
    field, camera, uv = scene.field, scene.camera, scene.uv
    dlts, params, limit_px = scene.dlts, scene.params, scene.limit_px
    empty = Deblended.empty()
    F = all_fundamentals(dlts)
    c, a, b = free_triples(scene, marker, F)
    if len(c) == 0:
        return empty
    xyz_a, xyz_b, ok = place_two(c, a, b, camera, uv, dlts, F, params, limit_px)
    c, a, b, xyz_a, xyz_b = c[ok], a[ok], b[ok], xyz_a[ok], xyz_b[ok]
    n = len(c)
    if n == 0:
        return empty
    own = np.concatenate([a, b])
    xyz = np.concatenate([xyz_a, xyz_b])
    f2 = np.concatenate([field[c], field[c]])
    virtual = len(field) + np.arange(2 * n)  # each half's image of c
    won = choose_pairs(own, virtual, xyz, f2, p_xyz, p_field, params, True, alone=False)
    both = won[:n] & won[n:]
    # a blob of two triples' winning halves: neither triple holds it
    both &= np.bincount(c[both], minlength=len(field))[c] == 1
    keep = np.r_[both, both]
    return Deblended(xyz[keep], f2[keep], np.zeros(int(keep.sum())), own[keep], np.r_[c, c][keep])


def free_triples(
    scene: MergeScene, marker: NDArray[np.int64], F: NDArray[np.float64]
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """Every free blob ``c`` with two free partners ``a``, ``b`` (blobs of other cameras
    in its field, each pair within ``epipolar_band_px``), each unordered {a, b} once."""
    field, camera, uv = scene.field, scene.camera, scene.uv
    free = np.flatnonzero((marker < 0) & scene.usable)
    band = scene.params.epipolar_band_px
    x, y, _ = candidate_pairs(field[free], camera[free], uv[free], F, band)
    x, y = free[x], free[y]
    c = np.concatenate([x, y])  # the pairs hold each direction once
    o = np.concatenate([y, x])
    order = np.lexsort((o, c))
    c, o = c[order], o[order]
    start = np.searchsorted(c, c, side="left")
    count = np.searchsorted(c, c, side="right") - start
    rep = np.maximum(count - 1, 0)
    i1 = np.repeat(np.arange(len(c)), rep)
    within = np.arange(rep.sum()) - np.repeat(np.cumsum(rep) - rep, rep)
    i2 = start[i1] + within + (start[i1] + within >= np.arange(len(c))[i1])
    keep = i1 < i2
    return c[i1[keep]], o[i1[keep]], o[i2[keep]]


def place_two(
    c: NDArray[np.int64],
    a: NDArray[np.int64],
    b: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    F: NDArray[np.float64],
    params: ReconParams,
    limit_px: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """The two markers of triples (merged blob ``c``, own blobs ``a``, ``b``), weights
    from their depths (equal first); ``ok`` where the solution is well conditioned,
    each image within ``deblend_radius_px`` of ``c`` and the points apart."""
    n, j = len(c), camera[c]
    la, lb = np.zeros((n, 3)), np.zeros((n, 3))
    for ci in np.unique(camera[a]):
        for cj in np.unique(j):
            s = (camera[a] == ci) & (j == cj)
            la[s] = epipolar_lines(F[ci, cj], uv[a[s]])
    for ci in np.unique(camera[b]):
        for cj in np.unique(j):
            s = (camera[b] == ci) & (j == cj)
            lb[s] = epipolar_lines(F[ci, cj], uv[b[s]])
    cc = uv[c]
    wa = wb = np.ones(n)
    for _ in range(3):
        # p_b = ((wa + wb) c - wa p_a) / wb on lb: a line that p_a lies on
        lbc = lb[:, 0] * cc[:, 0] + lb[:, 1] * cc[:, 1]
        mirror = np.column_stack([-wa * lb[:, 0], -wa * lb[:, 1], (wa + wb) * lbc + wb * lb[:, 2]])
        h = np.cross(la, mirror)
        with np.errstate(divide="ignore", invalid="ignore"):
            pa = h[:, :2] / h[:, 2:3]
            pb = ((wa + wb)[:, None] * cc - wa[:, None] * pa) / wb[:, None]
        obs = np.stack([uv[a], pa, uv[b], pb], axis=1).reshape(-1, 2)
        cams = np.column_stack([camera[a], j, camera[b], j]).ravel()
        t = triangulate_observations(dlts, np.repeat(np.arange(2 * n), 2), cams, obs, 2 * n, 0)
        xyz_a, xyz_b = t.xyz_mm[0::2], t.xyz_mm[1::2]
        da = depth_of(dlts, j, np.nan_to_num(xyz_a))
        db = depth_of(dlts, j, np.nan_to_num(xyz_b))
        wa, wb = 1.0 / np.maximum(da * da, 1e-18), 1.0 / np.maximum(db * db, 1e-18)
    sin = np.abs(la[:, 0] * lb[:, 1] - la[:, 1] * lb[:, 0])
    r = params.deblend_radius_px
    ok = np.all(np.isfinite(t.xyz_mm[0::2]) & np.isfinite(t.xyz_mm[1::2]), axis=1)
    ok &= (sin >= _MIN_SIN) & (np.linalg.norm(pa - cc, axis=1) <= r)
    ok &= np.linalg.norm(pb - cc, axis=1) <= r
    ok &= np.linalg.norm(pa - pb, axis=1) > 2.0 * limit_px
    ok &= np.linalg.norm(xyz_a - xyz_b, axis=1) >= params.group_radius_mm
    ok &= ~near_cameras(np.nan_to_num(xyz_a), dlts, params.camera_clearance_mm)
    ok &= ~near_cameras(np.nan_to_num(xyz_b), dlts, params.camera_clearance_mm)
    return xyz_a, xyz_b, ok


#: Smallest sine of the angle between the two epipolar lines through a merged blob: more
#: nearly parallel lines place the two markers along them by the noise alone.
_MIN_SIN = 0.1


def deblend_held(
    scene: MergeScene,
    marker: NDArray[np.int64],
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
    blob_row: NDArray[np.int64],
    p_rms: NDArray[np.float64],
    body: RigidTriangles,
) -> tuple[NDArray[np.int64], NDArray[np.float64], Deblended]:
    """:func:`deblend_pairs` where the merged blob ``c`` and one marker's own blob ``a``
    already make a two-camera point: a pair of blobs that agree along an epipolar line
    is taken whole, so the second marker in ``c`` (its own blob ``b`` free in a third
    camera) is left without an image, and the point, pulled to the centroid, sits off
    its marker. Both are placed as there; when both continue trajectories and win their
    blobs, the point moves to its half and the other half is a new point.

    Returns
    -------
    moved : ndarray of int
        Points (rows of ``p_xyz``) that move.
    moved_xyz : ndarray, shape (len(moved), 3)
        Where they move.
    new : Deblended
        The other markers.
    """
    field, camera, uv, usable = scene.field, scene.camera, scene.uv, scene.usable
    dlts, params, limit_px = scene.dlts, scene.params, scene.limit_px
    none = np.zeros(0, dtype=np.int64), np.zeros((0, 3)), Deblended.empty()
    held = blob_row >= 0
    # a point pulled by a centroid fits its two blobs worse than the trial's typical
    # marker does (a pair within the noise shows no second image in its blob)
    rms_ok = np.isfinite(p_rms)
    typical = np.median(p_rms[rms_ok]) if rms_ok.any() else np.inf
    two = np.flatnonzero((held.sum(axis=1) == 2) & (p_rms > typical))
    free = np.flatnonzero((marker < 0) & usable)
    if len(two) == 0 or len(free) == 0:
        return none
    rows = np.sort(blob_row[two], axis=1)[:, -2:]  # the point's two blobs
    P = np.r_[two, two]
    c, a = np.r_[rows[:, 0], rows[:, 1]], np.r_[rows[:, 1], rows[:, 0]]
    F = all_fundamentals(dlts)
    k, b = _partners(c, uv[c], free, field, camera, uv, F, params.epipolar_band_px)
    k, b = k[camera[b] != camera[a[k]]], b[camera[b] != camera[a[k]]]
    if len(k) == 0:
        return none
    P, c, a = P[k], c[k], a[k]
    xyz_a, xyz_b, ok = place_two(c, a, b, camera, uv, dlts, F, params, limit_px)
    # b is the point's own image in a third camera when the point projects onto it
    at_b = project_rows(dlts, camera[b], p_xyz[P])
    ok &= np.linalg.norm(at_b - uv[b], axis=1) > params.deblend_radius_px
    P, c, a, b, xyz_a, xyz_b = P[ok], c[ok], a[ok], b[ok], xyz_a[ok], xyz_b[ok]
    # the point's half continues the trajectory the point was taken for, through the
    # known points alone (moved halves of neighbouring fields support each other)
    step, tol = params.two_camera_step_mm, params.two_camera_continuity_mm
    ok = continuity_mm(xyz_a, field[c], p_xyz, p_field, step, tol) <= tol
    # the other half is a marker of the set: a segment's distances to two known points
    # (a single-view marker's ray through the blob's line places it anywhere along it);
    # a point that fits its segment must fit it better once freed of the centroid's pull
    tol_body = params.two_camera_body_mm
    ok &= body_error(xyz_b, field[c], p_xyz, p_field, body) <= tol_body
    was = body_error(p_xyz[P], field[c], p_xyz, p_field, body)
    ok &= (was > tol_body) | (body_error(xyz_a, field[c], p_xyz, p_field, body) <= was)
    P, c, a, b, xyz_a, xyz_b = P[ok], c[ok], a[ok], b[ok], xyz_a[ok], xyz_b[ok]
    n = len(P)
    if n == 0:
        return none
    own = np.r_[a, b]
    xyz, f2 = np.concatenate([xyz_a, xyz_b]), np.r_[field[c], field[c]]
    virtual = len(field) + np.arange(2 * n)
    won = choose_pairs(own, virtual, xyz, f2, p_xyz, p_field, params, True, alone=False)
    both = won[:n] & won[n:]
    both &= np.bincount(P[both], minlength=len(p_xyz))[P] == 1  # one way per point
    new = Deblended(xyz_b[both], field[c[both]], np.zeros(int(both.sum())), b[both], c[both])
    return P[both], xyz_a[both], new
