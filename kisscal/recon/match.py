"""Matching 2D blobs across cameras: the thesis' triple matching and Shafiq's central strategy.

Both strategies take a whole trial in long format (one row per blob: field, camera, u, v)
and return ``marker``: for every blob, the marker it was assigned to or -1. A blob ends in
at most one marker.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points, lexsort_ints
from kisscal.dlt.model import project_rows
from kisscal.dlt.triangulate import triangulate_observations
from kisscal.errors import InputError
from kisscal.recon.assign import accept, check_table, extend, finish, solve_one
from kisscal.recon.body import RigidTriangles
from kisscal.recon.epipolar import (
    all_fundamentals,
    candidate_pairs,
    distance_matrix_px,
    field_pairs,
)
from kisscal.recon.group import (
    Solved,
    first_per_key,
    near_cameras,
    renumber,
    residual_limit_px,
    triangulate_markers,
)
from kisscal.recon.pairs import match_two_camera
from kisscal.recon.params import DEFAULT_PARAMS, ReconParams
from kisscal.recon.stationary import at_epipoles


def _triangles(
    a: NDArray[np.int64], b: NDArray[np.int64], n: int
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """All triangles x < y < z of the graph with edges (a, b), a < b, without Python loops.

    Every wedge x - y - z (edges (x, y) and (y, z)) is a candidate; it is closed when
    (x, z) is an edge too. Edges are looked up in a table per node x over x+1 .. its
    largest neighbour, not searched: nodes are ranked so that the blobs of a field are
    consecutive, and the tables then hold no more cells than the field's blob pairs.
    """
    order = lexsort_ints((b, a))
    a, b = a[order], b[order]
    # the edges from each node: a CSR layout of the sorted edges
    offsets = np.r_[0, np.cumsum(np.bincount(a, minlength=n))]
    start, stop = offsets[b], offsets[b + 1]
    cnt = stop - start
    e = np.repeat(np.arange(len(a)), cnt)
    first = np.repeat(np.cumsum(cnt) - cnt, cnt)
    f = np.repeat(start, cnt) + (np.arange(len(e)) - first)
    x, y, z = a[e], b[e], b[f]
    has = offsets[1:] > offsets[:-1]
    last = np.where(has, b[np.maximum(offsets[1:] - 1, 0)] if len(b) else 0, -1)
    row = np.r_[0, np.cumsum(np.where(has, last - np.arange(n), 0))]
    table = np.zeros(int(row[-1]), dtype=bool)
    table[row[a] + (b - a - 1)] = True
    closed = z <= last[x]
    closed[closed] = table[row[x[closed]] + (z[closed] - x[closed] - 1)]
    return x[closed], y[closed], z[closed]


#: Fields whose candidate triples are formed at a time: their pairs and triangles are
#: the largest arrays of a trial's matching, so memory stays bounded for long trials.
TRIPLE_BLOCK_FIELDS = 200


def _field_blocks(sorted_field: NDArray[np.int64], fields: int) -> list[tuple[int, int]]:
    """``(start, stop)`` of runs of rows covering up to ``fields`` consecutive fields each
    (rows sorted by field; a block never splits a field)."""
    edges = np.flatnonzero(np.diff(sorted_field // fields)) + 1
    cuts = np.r_[0, edges, len(sorted_field)]
    return list(zip(cuts[:-1].tolist(), cuts[1:].tolist(), strict=True))


def _good_triples(
    rows: NDArray[np.int64],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    F: NDArray[np.float64],
    params: ReconParams,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """The triples of blobs among ``rows`` (sorted by field, camera) that are pairwise in
    each other's epipolar bands and reproject within ``max_rms_px``: rows, rms, 3D.

    Triples are field-local, so blocks of fields give the triples of the whole trial in
    the same order (by rank of their blobs).
    """
    pa, pb, _ = candidate_pairs(field[rows], camera[rows], uv[rows], F, params.epipolar_band_px)
    x, y, z = _triangles(pa, pb, len(rows))  # rows are in rank order: local index = rank
    tri = np.column_stack([rows[x], rows[y], rows[z]])
    if not len(tri):
        return tri, np.zeros(0), np.zeros((0, 3))
    t = triangulate_observations(
        dlts,
        np.repeat(np.arange(len(tri)), 3),
        camera[tri].ravel(),
        uv[tri].reshape(-1, 2),
        len(tri),
        0,  # the linear solution is close enough to rank triples and seed markers
    )
    good = t.rms_px <= params.max_rms_px
    return tri[good], t.rms_px[good], t.xyz_mm[good]


def _extend_all(
    marker: NDArray[np.int64],
    first_id: int,
    new_xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    radius_px: float,
) -> None:
    """Extend new markers to their other cameras (Shafiq et al. 2001, 4.1), all at once.

    The new markers are ``first_id``, ``first_id + 1``, ... (one per row of ``new_xyz``).
    Each free blob within ``radius_px`` of a new marker's projection in the blob's camera,
    where the marker has no blob yet, is a candidate; closest first, a blob joins one
    marker and a marker takes one blob per camera. ``marker`` is updated in place.
    """
    n_cam, n_new = len(dlts), len(new_xyz)
    free = np.flatnonzero(marker < 0)
    if len(free) == 0 or n_new == 0:
        return
    rows = np.flatnonzero((marker >= first_id) & (marker < first_id + n_new))
    slot = marker[rows] - first_id
    has = np.zeros((n_new, n_cam), dtype=bool)
    has[slot, camera[rows]] = True
    m_field = np.zeros(n_new, dtype=np.int64)
    m_field[slot] = field[rows]
    free = free[lexsort_ints([field[free]])]
    mo = lexsort_ints([m_field])
    fi, mi = field_pairs(field[free], m_field[mo])
    b, m = free[fi], mo[mi]
    lacking = ~has[m, camera[b]]
    b, m = b[lacking], m[lacking]
    if len(b) == 0:
        return
    # each marker projected once into every camera, not once per candidate blob
    proj = project_rows(dlts, np.tile(np.arange(n_cam), n_new), np.repeat(new_xyz, n_cam, 0))
    at = m * n_cam + camera[b]
    du, dv = uv[b, 0] - proj[at, 0], uv[b, 1] - proj[at, 1]
    d = np.sqrt(du * du + dv * dv)  # np.linalg.norm's sum, on 1-D arrays
    near = d <= radius_px
    b, m, d = b[near], m[near], d[near]
    keep = first_per_key(b, d)  # a blob joins its closest marker
    b, m, d = b[keep], m[keep], d[keep]
    keep = first_per_key(m * n_cam + camera[b], d)  # one blob per marker and camera
    marker[b[keep]] = first_id + m[keep]


def match_triple(
    field: ArrayLike,
    camera: ArrayLike,
    uv: ArrayLike,
    dlts: ArrayLike,
    params: ReconParams = DEFAULT_PARAMS,
    F: NDArray[np.float64] | None = None,
    solved: Solved | None = None,
) -> NDArray[np.int64]:
    """Triple matching over a whole trial (Küçük 2005, 3.3.5-3.3.7), vectorised.

    Three blobs of three cameras form a triple when every one lies within the epipolar band
    of the other two's lines (eq. 3.9) and their 3-camera DLT solution reprojects within
    ``max_rms_px``. Triples become markers best (lowest ``rms_px``) first, each blob used
    once: in rounds, every triple that is the best remaining triple of all three of its
    blobs is accepted, then extended to the cameras it lacks with the free blob nearest its
    projection within ``search_radius_px``. (Taking triples one by one would be a Python
    loop; when two disjoint triples of one marker win in the same round, the 3D grouping
    below unites them.)
    Finally 3D points of one field closer than ``group_radius_mm`` that do not conflict are
    united (3.3.7) and markers over the residual limit (:func:`residual_limit_px`) are split
    or dropped.

    Parameters
    ----------
    field, camera : array_like of int, shape (n,)
        Field and camera index of each blob.
    uv : array_like, shape (n, 2)
        Linearised pixel coordinates.
    dlts : array_like, shape (n_cameras, 11)
        DLT parameters of each camera.
    params : ReconParams
    F : ndarray, optional
        Precomputed :func:`~kisscal.recon.epipolar.all_fundamentals`.
    solved : Solved, optional
        Markers of this table triangulated before (:class:`~kisscal.recon.group.Solved`);
        takes the last triangulation of the markers returned.

    Returns
    -------
    ndarray of int, shape (n,)
        Marker of each blob (-1: unmatched), markers numbered in field order.
    """
    dlts = np.asarray(dlts, dtype=float)
    field, camera, uv = check_table(field, camera, uv, len(dlts))
    n = len(field)
    marker = np.full(n, -1, dtype=np.int64)
    if n == 0:
        return marker
    F = all_fundamentals(dlts) if F is None else F
    # rank blobs by (field, camera) so that every pair and triple is increasing in rank
    order = lexsort_ints((camera, field))
    parts = [
        _good_triples(order[a:b], field, camera, uv, dlts, F, params)
        for a, b in _field_blocks(field[order], TRIPLE_BLOCK_FIELDS)
    ]
    tri = np.concatenate([p[0] for p in parts])
    tri_rms = np.concatenate([p[1] for p in parts])
    tri_xyz = np.concatenate([p[2] for p in parts])
    next_id = 0
    while len(tri):
        # the best triple of each blob: the lowest rms_px, ties to the first triple (as
        # ranks in one stable sort of the triples, cheaper than sorting their blobs)
        rank = np.empty(len(tri), dtype=np.int64)
        rank[np.argsort(tri_rms, kind="stable")] = np.arange(len(tri))
        best_of_blob = np.full(n, len(tri), dtype=np.int64)
        np.minimum.at(best_of_blob, tri.ravel(), np.repeat(rank, 3))
        won = np.all(best_of_blob[tri] == rank[:, None], axis=1)
        first_id, next_id = next_id, next_id + int(won.sum())
        marker[tri[won]] = np.arange(first_id, next_id)[:, None]
        extend = field, camera, uv, dlts, params.search_radius_px
        _extend_all(marker, first_id, tri_xyz[won], *extend)
        alive = np.all(marker[tri] < 0, axis=1)
        tri, tri_rms, tri_xyz = tri[alive], tri_rms[alive], tri_xyz[alive]
    return finish(marker, field, camera, uv, dlts, params, solved=solved)


def _transfer_ok(
    rows: tuple[int, int, int],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    radius_px: float,
) -> tuple[bool, NDArray[np.float64]]:
    """Verify a candidate triplet in all three cameras (Shafiq et al. 2001, Fig. 16).

    Each point must lie within ``radius_px`` of the intersection of the epipolar lines of
    the other two. That intersection is the projection of the two other points' 3D
    intersection; computing it that way keeps the test defined when the two lines are
    parallel (collinear camera centres), where the line intersection is not.
    """
    r = np.asarray(rows)
    L = dlts[camera[r]]
    points = []
    for k, (i, j) in enumerate(((1, 2), (0, 2), (0, 1))):
        xyz, _ = solve_one(L[[i, j]], uv[r[[i, j]]], 0)
        if not np.all(np.isfinite(xyz)):
            return False, xyz
        d = project_rows(dlts, camera[r[k : k + 1]], xyz[None, :])[0] - uv[r[k]]
        if np.hypot(d[0], d[1]) > radius_px:
            return False, xyz
        points.append(xyz)
    return True, np.mean(points, axis=0)


def match_central(
    field: ArrayLike,
    camera: ArrayLike,
    uv: ArrayLike,
    dlts: ArrayLike,
    params: ReconParams = DEFAULT_PARAMS,
    F: NDArray[np.float64] | None = None,
    solved: Solved | None = None,
) -> NDArray[np.int64]:
    """Shafiq et al. (2001, 4.1) central strategy, field by field.

    For each base camera in turn and each of its unmatched blobs: the other cameras' unmatched
    blobs within the epipolar band are candidates (closest ``max_candidates`` per camera);
    cameras are prioritised by their closest candidate. Candidate triplets (base, priority
    camera r, priority camera s) are tried best candidates first; a triplet is verified when
    each point lies within ``search_radius_px`` of the intersection of the other two's
    epipolar lines. A verified triplet is extended to the remaining cameras and its blobs are
    excluded from further search. (Shafiq pairs a base blob with its closest candidate when
    only one candidate camera exists; here :func:`match_trial` makes two-camera markers for
    both strategies, see :mod:`kisscal.recon.pairs`.)

    Parameters and return value as :func:`match_triple`.
    """
    dlts = np.asarray(dlts, dtype=float)
    field, camera, uv = check_table(field, camera, uv, len(dlts))
    n = len(field)
    marker = np.full(n, -1, dtype=np.int64)
    if n == 0:
        return marker
    F = all_fundamentals(dlts) if F is None else F
    n_cam = len(dlts)
    order = lexsort_ints((camera, field))
    f_sorted = field[order]
    cuts = np.flatnonzero(np.r_[True, f_sorted[1:] != f_sorted[:-1], True])
    next_id = 0
    for s0, e0 in itertools.pairwise(cuts):
        rows_f = order[s0:e0]
        cam_rows = [rows_f[camera[rows_f] == c] for c in range(n_cam)]
        dist = _field_distances(cam_rows, uv, F)
        for c1 in range(n_cam):
            for p_local, p in enumerate(cam_rows[c1]):
                if marker[p] >= 0:
                    continue
                cands = _central_candidates(dist, c1, p_local, cam_rows, marker, params)
                got = _first_verified(int(p), c1, cands, rows_f, marker, camera, uv, dlts, params)
                if got:
                    marker[got] = next_id
                    next_id += 1
    return finish(marker, field, camera, uv, dlts, params, solved=solved)


def _field_distances(
    cam_rows: list[NDArray[np.int64]], uv: NDArray[np.float64], F: NDArray[np.float64]
) -> dict[tuple[int, int], NDArray[np.float64]]:
    """Epipolar distances (px) between every two cameras' blobs of one field."""
    dist: dict[tuple[int, int], NDArray[np.float64]] = {}
    for i, j in itertools.combinations(range(len(cam_rows)), 2):
        if len(cam_rows[i]) and len(cam_rows[j]):
            dist[i, j] = distance_matrix_px(F[i, j], uv[cam_rows[i]], uv[cam_rows[j]])
            dist[j, i] = dist[i, j].T
    return dist


def _central_candidates(
    dist: dict[tuple[int, int], NDArray[np.float64]],
    c1: int,
    p_local: int,
    cam_rows: list[NDArray[np.int64]],
    marker: NDArray[np.int64],
    params: ReconParams,
) -> dict[int, NDArray[np.int64]]:
    """Unmatched blobs within the epipolar band of a base blob, per camera (closest
    ``max_candidates`` each), cameras in order of their closest candidate."""
    cands: dict[int, NDArray[np.int64]] = {}
    best: dict[int, float] = {}
    for k in range(len(cam_rows)):
        if (c1, k) not in dist:
            continue
        d = dist[c1, k][p_local]
        ok = np.flatnonzero((d < params.epipolar_band_px) & (marker[cam_rows[k]] < 0))
        if len(ok):
            ok = ok[np.argsort(d[ok], kind="stable")][: params.max_candidates]
            cands[k] = cam_rows[k][ok]
            best[k] = float(d[ok[0]])
    return {k: cands[k] for k in sorted(cands, key=best.__getitem__)}


def _first_verified(
    p: int,
    c1: int,
    cands: dict[int, NDArray[np.int64]],
    rows_f: NDArray[np.int64],
    marker: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    params: ReconParams,
) -> list[int]:
    """The blobs of the first triplet (priority cameras first, best candidates first) that
    passes the transfer test and is accepted once extended; empty when none does."""
    priority = list(cands)
    for ir, r in enumerate(priority):
        for s in priority[ir + 1 :]:
            for qr, qs in itertools.product(cands[r], cands[s]):
                ok, xyz = _transfer_ok(
                    (p, int(qr), int(qs)), camera, uv, dlts, params.search_radius_px
                )
                if not ok:
                    continue
                members = {c1: p, r: int(qr), s: int(qs)}
                free = rows_f[marker[rows_f] < 0]
                got = extend(members, xyz, free, camera, uv, dlts, params.search_radius_px)
                got = accept(got, camera, uv, dlts, params, 3)
                if got:
                    return got
    return []


def match_trial(
    field: ArrayLike,
    camera: ArrayLike,
    uv: ArrayLike,
    dlts: ArrayLike,
    params: ReconParams = DEFAULT_PARAMS,
    solved: Solved | None = None,
    body: RigidTriangles | None = None,
    rate_hz: float = 50.0,
) -> NDArray[np.int64]:
    """Match a whole trial with the strategy named by ``params.strategy``.

    Markers seen by three or more cameras first (twice: blobs freed by the residual limit
    get a second chance), then, if ``params.allow_two_camera``, two-camera markers of the
    blobs left over (:func:`kisscal.recon.pairs.match_two_camera`). Markers that are LED
    rings are dropped: those at a camera (``params.camera_clearance_mm``) and those whose
    every blob lies at an epipole (``params.led_radius_px``).

    ``solved`` (:class:`~kisscal.recon.group.Solved`, optional) carries the markers'
    triangulations from step to step (each step solves only the markers it changed) and
    ends with a triangulation of markers of this table, for the caller to reuse. ``body``
    (:class:`~kisscal.recon.body.RigidTriangles`, optional) and the field rate ``rate_hz``
    go to the two-camera step.

    Returns
    -------
    ndarray of int, shape (n,)
        Marker of each blob, -1 for unmatched blobs.
    """
    dlts = np.asarray(dlts, dtype=float)
    field, camera, uv = check_table(field, camera, uv, len(dlts))
    fn = match_triple if params.strategy == "triple" else match_central
    F = all_fundamentals(dlts)
    led = at_epipoles(camera, uv, dlts, params.led_radius_px)
    solved = Solved() if solved is None else solved
    marker = fn(field, camera, uv, dlts, params, F, solved)
    marker, rms = _drop_leds(marker, field, camera, uv, dlts, params, led, solved)
    # the leftovers are the trial's worst blobs: keep the limit the whole trial set
    limit = residual_limit_px(rms, params) if len(rms) else None
    free = np.flatnonzero(marker < 0)
    if len(free) >= 3 and limit is not None:
        # second chance for blobs freed by the residual limit (a blob wrongly attached to
        # a neighbour is split off there, and may complete its own marker now)
        fixed = replace(params, max_rms_px=limit, outlier_rms_factor=0.0)
        sub = field[free], camera[free], uv[free]
        solved_sub = Solved()  # of the table of free blobs
        again = fn(*sub, dlts, fixed, F, solved_sub)
        again, _ = _drop_leds(again, *sub, dlts, params, led[free], solved_sub)
        found = again >= 0
        marker[free[found]] = again[found] + marker.max() + 1
        marker = renumber(marker, field)
    if params.allow_two_camera and np.count_nonzero(marker < 0) >= 2:
        marker, _ = match_two_camera(
            marker, field, camera, uv, dlts, params, limit, F, led, solved, body, rate_hz
        )
    return marker


def _drop_leds(
    marker: NDArray[np.int64],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    params: ReconParams,
    led: NDArray[np.bool_],
    solved: Solved | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Markers that are LED rings dropped (at a camera, or every blob at an epipole:
    ``led``); the ``rms_px`` of the others."""
    if not (marker >= 0).any():
        return marker, np.zeros(0)
    tri = triangulate_markers(marker, camera, uv, dlts, params.reweight_iterations, solved)
    rows = np.flatnonzero(marker >= 0)
    seen_elsewhere = np.bincount(marker[rows], ~led[rows], minlength=len(tri.rms_px)) > 0
    bad = ~seen_elsewhere | near_cameras(tri.xyz_mm, dlts, params.camera_clearance_mm)
    if bad.any():
        marker = renumber(np.where((marker >= 0) & bad[np.maximum(marker, 0)], -1, marker), field)
    return marker, tri.rms_px[~bad]


def match_field(
    points_per_camera: list[ArrayLike],
    dlts: ArrayLike,
    params: ReconParams = DEFAULT_PARAMS,
) -> list[dict[int, int]]:
    """Match the blobs of one field.

    Parameters
    ----------
    points_per_camera : list of array_like, each shape (n_c, 2)
        Linearised blob centroids of each camera (camera order = rows of ``dlts``).
    dlts : array_like, shape (n_cameras, 11)
    params : ReconParams

    Returns
    -------
    list of dict
        One dict per marker: camera index -> blob index within that camera's list.
    """
    dlts = np.asarray(dlts, dtype=float)
    if len(points_per_camera) != len(dlts):
        raise InputError(
            f"match_field: {len(points_per_camera)} point lists for {len(dlts)} cameras"
        )
    pts = [as_points(p, 2, f"points of camera {c}") for c, p in enumerate(points_per_camera)]
    camera = np.concatenate([np.full(len(p), c) for c, p in enumerate(pts)]).astype(np.int64)
    local = np.concatenate([np.arange(len(p)) for p in pts]).astype(np.int64)
    uv = np.concatenate(pts) if pts else np.zeros((0, 2))
    marker = match_trial(np.zeros(len(uv), dtype=np.int64), camera, uv, dlts, params)
    out: list[dict[int, int]] = [{} for _ in range(int(marker.max()) + 1 if len(marker) else 0)]
    for r in np.flatnonzero(marker >= 0):
        out[marker[r]][int(camera[r])] = int(local[r])
    return out
