"""Markers as sets of 2D observations: final triangulation, splitting, 3D point groups.

A marker is represented by ``marker`` — one integer per 2D blob, the marker the blob belongs
to or -1 — so that "each 2D blob ends in at most one 3D marker" holds by construction.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from kisscal.dlt.model import camera_centre_mm
from kisscal.dlt.triangulate import Triangulation, triangulate_observations
from kisscal.recon.params import ReconParams

#: Lab x offset (mm) per field, so that one k-d tree holds every field of a trial apart.
_FIELD_SEPARATION_MM = 1e7


def embed_fields(xyz: NDArray[np.float64], field: NDArray[np.int64]) -> NDArray[np.float64]:
    """Points (3D in mm, or image points in px) with their field's offset in the first
    coordinate (:data:`_FIELD_SEPARATION_MM` per field), so that one k-d tree holds the
    points of every field of a trial apart."""
    out = xyz.copy()
    out[:, 0] += field * _FIELD_SEPARATION_MM
    return out


def renumber(marker: NDArray[np.int64], field: NDArray[np.int64]) -> NDArray[np.int64]:
    """Renumber markers 0..m-1 in order of (field, old id); -1 stays -1.

    The field of a marker is that of its first blob. Called after every change of the
    markers, so it works with tables indexed by id (no sort of the blobs) when the ids are
    not far more than the blobs.
    """
    out = np.full(len(marker), -1, dtype=np.int64)
    used = np.flatnonzero(marker >= 0)
    if len(used) == 0:
        return out
    mu = marker[used]
    top = int(mu.max()) + 1
    if top > 4 * len(marker) + 64:  # sparse ids: tables by id would be mostly empty
        ids, first = np.unique(mu, return_index=True)
        slot = np.searchsorted(ids, mu)
    else:
        first_of = np.full(top, len(mu), dtype=np.int64)
        np.minimum.at(first_of, mu, np.arange(len(mu)))
        present = first_of < len(mu)
        ids = np.flatnonzero(present)
        first = first_of[ids]
        slot = (np.cumsum(present) - 1)[mu]
    order = np.lexsort((ids, field[used][first]))
    new_id = np.empty(len(ids), dtype=np.int64)
    new_id[order] = np.arange(len(ids))
    out[used] = new_id[slot]
    return out


class Solved:
    """The last triangulation of a trial's markers, for the next one to reuse.

    A point's solution depends on its own observations alone, summed in row order (see
    :func:`~kisscal.dlt.triangulate.triangulate_observations`), so a marker made of exactly
    the blobs of a marker solved before has bitwise the same position, rms and residuals.
    The steps of a trial's matching (grouping, the residual limit, LED rings, second
    chance, pairs) change a few markers at a time and triangulate all of them after each
    step: with one ``Solved`` shared by the steps of one 2D table, each solves only the
    markers that changed.
    """

    def __init__(self) -> None:
        self.marker: NDArray[np.int64] | None = None
        self.tri: Triangulation | None = None

    def remember(self, marker: NDArray[np.int64], tri: Triangulation) -> None:
        """Keep ``tri`` as the triangulation of (a copy of) ``marker``."""
        self.marker, self.tri = marker.copy(), tri

    def expanded(self, rows: NDArray[np.int64], n: int) -> Solved:
        """The same markers in a larger table whose rows ``rows`` (ascending) are this
        table's rows, the other rows unmatched."""
        out = Solved()
        if self.marker is not None and self.tri is not None:
            marker = np.full(n, -1, dtype=np.int64)
            marker[rows] = self.marker
            out.remember(marker, self.tri)
        return out


def triangulate_markers(
    marker: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    reweight_iterations: int,
    solved: Solved | None = None,
) -> Triangulation:
    """Triangulate every marker from all its observations (markers must be 0..m-1).

    ``solved`` (of this table, DLTs and ``reweight_iterations``) supplies the markers
    solved before and takes this result.
    """
    rows = np.flatnonzero(marker >= 0)
    n = int(marker.max()) + 1 if len(rows) else 0
    if solved is None or solved.marker is None or solved.tri is None:
        tri = triangulate_observations(
            dlts, marker[rows], camera[rows], uv[rows], n, reweight_iterations
        )
    else:
        tri = _reuse(
            marker, rows, n, solved.marker, solved.tri, camera, uv, dlts, reweight_iterations
        )
    if solved is not None:
        solved.remember(marker, tri)
    return tri


def _reuse(
    marker: NDArray[np.int64],
    rows: NDArray[np.int64],
    n: int,
    before: NDArray[np.int64],
    tri_before: Triangulation,
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    reweight_iterations: int,
) -> Triangulation:
    """:func:`triangulate_markers` of the markers of ``rows``, taking the results of
    markers made of exactly the blobs of one of ``before`` from ``tri_before``."""
    m, old = marker[rows], before[rows]
    count = np.bincount(m, minlength=n)
    count_before = np.bincount(before[before >= 0], minlength=len(tri_before.rms_px))
    # same blobs: all of them in one earlier marker, which had no other blob
    lo = np.full(n, len(count_before), dtype=np.int64)
    hi = np.full(n, -1, dtype=np.int64)
    np.minimum.at(lo, m, old)
    np.maximum.at(hi, m, old)
    same = (lo == hi) & (lo >= 0)
    same[same] = count[same] == count_before[lo[same]]
    xyz = np.empty((n, 3))
    rms = np.empty(n)
    residual = np.empty(len(rows))
    xyz[same], rms[same] = tri_before.xyz_mm[lo[same]], tri_before.rms_px[lo[same]]
    kept = same[m]
    position_before = np.cumsum(before >= 0) - 1  # row -> index of tri_before.residual_px
    residual[kept] = tri_before.residual_px[position_before[rows[kept]]]
    redo = np.flatnonzero(~same)
    if len(redo):
        slot = np.cumsum(~same) - 1
        part = triangulate_observations(
            dlts,
            slot[m[~kept]],
            camera[rows[~kept]],
            uv[rows[~kept]],
            len(redo),
            reweight_iterations,
        )
        xyz[redo], rms[redo], residual[~kept] = part.xyz_mm, part.rms_px, part.residual_px
    return Triangulation(xyz, rms, count, residual)


def split_or_drop(
    marker: NDArray[np.int64],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    max_rms_px: float,
    min_cameras: int,
    reweight_iterations: int,
    solved: Solved | None = None,
) -> NDArray[np.int64]:
    """Enforce the residual limit: drop worst observations of bad markers, then bad markers.

    A marker whose reprojection ``rms_px`` exceeds ``max_rms_px`` loses its single worst
    observation (that blob is split off and becomes unmatched) and is re-triangulated, until
    it is good or has fewer than ``min_cameras`` observations, when it is dropped. All bad
    markers are handled together, one observation per round. ``solved``: see
    :func:`triangulate_markers`.

    Returns
    -------
    ndarray of int
        The new ``marker`` array, renumbered 0..m-1 in field order.
    """
    marker = renumber(marker, field)
    while True:
        counts = np.bincount(marker[marker >= 0]) if (marker >= 0).any() else np.zeros(0, int)
        small = counts < min_cameras
        if small.any():
            marker = np.where((marker >= 0) & small[np.maximum(marker, 0)], -1, marker)
            marker = renumber(marker, field)
            continue
        if not (marker >= 0).any():
            return marker
        tri = triangulate_markers(marker, camera, uv, dlts, reweight_iterations, solved)
        bad = ~(tri.rms_px <= max_rms_px)
        if not bad.any():
            return marker
        rows = np.flatnonzero(marker >= 0)
        in_bad = bad[marker[rows]]
        rows, resid = rows[in_bad], tri.residual_px[in_bad]
        # worst observation of each bad marker: last of its rows sorted by residual
        order = np.lexsort((np.nan_to_num(resid, nan=np.inf), marker[rows]))
        m_sorted = marker[rows][order]
        last = np.r_[m_sorted[1:] != m_sorted[:-1], True]
        marker = marker.copy()
        marker[rows[order][last]] = -1
        marker = renumber(marker, field)


def merge_groups(
    marker: NDArray[np.int64],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    radius_mm: float,
    max_rms_px: float,
    reweight_iterations: int,
    solved: Solved | None = None,
) -> NDArray[np.int64]:
    """Unite 3D points of one field that belong to one marker (Küçük 2005, 3.3.7).

    Points of the same field closer than ``radius_mm`` form a group ("cloud"); two points are
    united when they do not claim different blobs of the same camera and the union,
    re-triangulated from all its 2D observations, keeps ``rms_px <= max_rms_px``.
    ``solved``: see :func:`triangulate_markers`.

    Returns
    -------
    ndarray of int
        The new ``marker`` array, renumbered.
    """
    marker = renumber(marker, field)
    if not (marker >= 0).any():
        return marker
    n_cam = len(dlts)
    tri = triangulate_markers(marker, camera, uv, dlts, reweight_iterations, solved)
    rows = np.flatnonzero(marker >= 0)
    m_field = np.zeros(len(tri.xyz_mm), dtype=np.int64)
    m_field[marker[rows]] = field[rows]
    finite = np.all(np.isfinite(tri.xyz_mm), axis=1)
    # separate fields by far more than any radius so one tree serves the whole trial
    pts = tri.xyz_mm.copy()
    pts[:, 0] += m_field * 1e7
    idx = np.flatnonzero(finite)
    if len(idx) < 2:
        return marker
    pairs = cKDTree(pts[idx]).query_pairs(radius_mm, output_type="ndarray")
    if len(pairs) == 0:
        return marker
    # blob row of each (marker, camera); -1 where the marker has no observation there
    blob = np.full((len(tri.xyz_mm), n_cam), -1, dtype=np.int64)
    blob[marker[rows], camera[rows]] = rows
    marker = marker.copy()
    parent = np.arange(len(tri.xyz_mm))

    def root(k: int) -> int:
        while parent[k] != k:
            k = parent[k]
        return k

    pairs = idx[pairs]
    dist = np.linalg.norm(pts[pairs[:, 0]] - pts[pairs[:, 1]], axis=1)
    pairs = pairs[np.argsort(dist, kind="stable")]
    bp, bq = blob[pairs[:, 0]], blob[pairs[:, 1]]
    compatible = ~np.any((bp >= 0) & (bq >= 0) & (bp != bq), axis=1)
    pairs, bp, bq = pairs[compatible], bp[compatible], bq[compatible]
    if len(pairs) == 0:
        return marker
    # judge every candidate union in one batch; chains of unions are rare (a marker split
    # in three) and are re-checked by the caller's residual limit
    union = np.where(bp >= 0, bp, bq)
    k, cam = np.nonzero(union >= 0)
    obs = union[k, cam]
    t = triangulate_observations(dlts, k, camera[obs], uv[obs], len(pairs), reweight_iterations)
    for (p, q), ok in zip(pairs, t.rms_px <= max_rms_px, strict=True):
        rp, rq = root(int(p)), root(int(q))
        if not ok or rp == rq:
            continue
        brp, brq = blob[rp], blob[rq]
        if np.any((brp >= 0) & (brq >= 0) & (brp != brq)):
            continue
        merged = np.where(brp >= 0, brp, brq)
        parent[rq] = rp
        blob[rp] = merged
        marker[merged[merged >= 0]] = rp
    return renumber(marker, field)


def first_per_key(key: NDArray[np.int64], score: NDArray[np.float64]) -> NDArray[np.int64]:
    """Indices of the lowest-score entry of each distinct key (ties: lowest index)."""
    order = np.lexsort((score, key))  # stable: equal scores keep index order
    if len(order) == 0:
        return order
    first = np.r_[True, key[order][1:] != key[order][:-1]]
    return order[first]


def residual_limit_px(rms_px: NDArray[np.float64], params: ReconParams) -> float:
    """The reprojection limit of a trial: ``max_rms_px``, tightened to
    ``outlier_rms_factor`` times the median ``rms_px`` of the trial's markers (never below
    ``outlier_floor_px``), so that a marker far noisier than its trial is treated as wrong."""
    rms_px = rms_px[np.isfinite(rms_px)]
    if params.outlier_rms_factor <= 0 or len(rms_px) == 0:
        return params.max_rms_px
    adaptive = max(params.outlier_floor_px, params.outlier_rms_factor * float(np.median(rms_px)))
    return min(params.max_rms_px, adaptive)


def near_cameras(
    xyz_mm: NDArray[np.float64], dlts: NDArray[np.float64], clearance_mm: float
) -> NDArray[np.bool_]:
    """Points closer than ``clearance_mm`` to a camera's projection centre.

    Another camera's LED ring, seen by two cameras, reconstructs at that camera; so does
    its image paired with any blob of that camera (both rays pass through its centre). No
    marker is ever there. NaN points are not near.
    """
    out = np.zeros(len(xyz_mm), dtype=bool)
    ok = np.all(np.isfinite(xyz_mm), axis=1)
    if clearance_mm <= 0 or not ok.any():
        return out
    centres = np.array([camera_centre_mm(L) for L in dlts])
    out[ok] = cKDTree(centres).query(xyz_mm[ok])[0] < clearance_mm
    return out
