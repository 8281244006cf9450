"""Single-camera fill: a filled marker moved onto the ray of a camera that still sees it.

Where a marker is seen by one camera only (the other leg hides it from the rest), no 3D
point is made, and the body's fill (rigid-body, two-marker, pattern or spline) estimates
it; the camera's blob is still there, unused by any 3D point. The marker lies on that
blob's ray, so two of its three coordinates are measured: the filled position is moved to
the point that best agrees with both the body's estimate (weight ``1 / prior_sd²``) and
the rays of the blobs found near its projection (weight ``1 / (ray_px x pixel size)²``
each): with one ray, the point on the ray nearest the estimate; with two, nearly their
triangulation. Only the error along the ray is left, which is about a third of the
estimate's when its error has no preferred direction.

A blob counts when it is the one unused blob of its camera and field within
``ray_fill_gate`` estimate errors (converted to pixels at the marker) of the estimate's
projection, and the next one in that camera is at least twice as far.

References
----------
Hartley & Zisserman 2004 (rays of a projective camera; least-squares point from rays);
Gløersen & Federolf 2016 (filling from the other markers of the body).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points
from kisscal.dlt.model import camera_centre_mm, pixel_size_mm, project_rows, ray_directions
from kisscal.errors import InputError
from kisscal.tracking.params import TrackingParams


@dataclass(frozen=True)
class SpareBlobs:
    """2D observations that no 3D point used, with the cameras that made them.

    Attributes
    ----------
    field : (n,) int array
        Field of each observation (ascending).
    camera : (n,) int array
        Camera (row of ``dlts``) of each observation.
    uv_px : (n, 2) float array
        Ideal (linearised) pixel coordinates, as the DLT maps lab points to.
    dlts : (n_cameras, 11) float array
        DLT parameters of every camera.
    free : (n,) bool array
        Observations not yet taken by a fill (a blob fills one marker only).
    point : (n,) int array or None
        Row of the 3D point that used each observation, -1 for none (those of points
        no named track holds are freed: :func:`freed`); None: only unused ones held.
    track : (n,) int array or None
        The track holding that point (:func:`freed`), -1 for none.
    """

    field: NDArray[np.int64]
    camera: NDArray[np.int64]
    uv_px: NDArray[np.float64]
    dlts: NDArray[np.float64]
    free: NDArray[np.bool_]
    point: NDArray[np.int64] | None = None
    track: NDArray[np.int64] | None = None

    @property
    def centres(self) -> NDArray[np.float64]:
        """Projection centre (mm) of each camera, (n_cameras, 3)."""
        return np.array([camera_centre_mm(L) for L in self.dlts]).reshape(-1, 3)

    def rows(self, lo: int, hi: int) -> NDArray[np.int64]:
        """Rows of free observations in fields [lo, hi)."""
        a, b = np.searchsorted(self.field, [lo, hi])
        rows = np.arange(a, b)
        return rows[self.free[rows]]


def spare_blobs(
    field: ArrayLike,
    camera: ArrayLike,
    uv_px: ArrayLike,
    dlts: ArrayLike,
    point: ArrayLike | None = None,
) -> SpareBlobs:
    """Build :class:`SpareBlobs` from unused observations (any order) and the cameras;
    with ``point``, observations 3D points used too (the point's row, -1 for none).

    Raises
    ------
    InputError
        Mismatched lengths, a camera index outside ``dlts`` or DLTs not of 11 values.
    """
    f = np.asarray(field, dtype=np.int64).ravel()
    c = np.asarray(camera, dtype=np.int64).ravel()
    uv = as_points(uv_px, 2, "uv_px")
    L = np.asarray(dlts, dtype=float)
    if L.ndim != 2 or L.shape[1] != 11:
        raise InputError(f"dlts: expected (n_cameras, 11), got {L.shape}")
    if not f.size == c.size == len(uv):
        raise InputError(f"spare blobs: {f.size} fields, {c.size} cameras, {len(uv)} uv rows")
    if c.size and (c.min() < 0 or c.max() >= len(L)):
        raise InputError(f"spare blobs: camera index outside 0..{len(L) - 1}")
    p = np.full(f.size, -1) if point is None else np.asarray(point, dtype=np.int64).ravel()
    if p.size != f.size:
        raise InputError(f"spare blobs: {f.size} fields, {p.size} points")
    order = np.argsort(f, kind="stable")
    order = order[np.all(np.isfinite(uv[order]), axis=1)]
    p = None if point is None else p[order]
    free = np.ones(order.size, dtype=bool) if p is None else p < 0
    return SpareBlobs(f[order], c[order], uv[order], L, free, p)


def freed(
    spare: SpareBlobs, point: NDArray, track: NDArray, held: NDArray | None = None
) -> SpareBlobs:
    """``spare`` (``free`` copied) with the blobs of the points ``point`` (rows) free, each
    marked with its track of ``track``: the points of tracks the labelling named no marker
    hold blobs a named marker's fill may need (kiss 3 seed 415: the crossing of a heel's
    and an ankle's single rays, 66 mm from the heel, held the heel's only blob 13 fields).
    With ``held`` (the rows of every point a track holds), the blobs of points no track
    holds are free too (lowcost 4 seed 427: a 5-field ghost, its track too short to keep,
    held an ankle's own blob in its second camera while the ankle's blob in the first was
    merged with the heel's; on that blob alone the ankle was placed 16 mm off)."""
    if spare.point is None:
        return dataclasses.replace(spare, free=spare.free.copy())
    of = np.full(max(int(spare.point.max(initial=-1)), int(point.max(initial=-1))) + 2, -1)
    of[point] = track
    own = of[spare.point]  # a point's row -1 reads the last slot, -1
    free = spare.free | (own >= 0)
    if held is not None:
        loose = spare.point >= 0
        loose[np.isin(spare.point, held)] = False
        free |= loose
    return dataclasses.replace(spare, free=free, track=own)


def _pick(
    k: NDArray, cam: NDArray, dist: NDArray, gate: NDArray, n_cameras: int
) -> NDArray[np.bool_]:
    """Of rows (field offset ``k``, camera ``cam``, distance ``dist`` px to the estimate),
    the one per (field, camera) within ``gate`` whose runner-up is at least twice as far."""
    cell = k * n_cameras + cam
    order = np.lexsort((dist, cell))
    cell_o, dist_o = cell[order], dist[order]
    first = np.r_[True, cell_o[1:] != cell_o[:-1]]
    nxt = np.r_[dist_o[1:], np.inf]
    same_next = np.r_[cell_o[1:] == cell_o[:-1], False]
    runner = np.where(same_next, nxt, np.inf)
    keep = first & (dist_o <= gate[order]) & (runner >= 2.0 * dist_o)
    out = np.zeros(k.size, dtype=bool)
    out[order[keep]] = True
    return out


def ray_correct(
    prior: NDArray,
    first_field: int,
    prior_sd_mm: float,
    spare: SpareBlobs,
    params: TrackingParams,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]]:
    """Move a filled stretch onto the rays of the unused blobs that see it (see module).

    Parameters
    ----------
    prior : (n, 3) array
        The body's fill of fields ``first_field .. first_field + n - 1`` (mm).
    first_field : int
    prior_sd_mm : float
        Its expected error (mm): the estimate's weight and the search gate.
    spare : SpareBlobs
    params : TrackingParams
        ``ray_fill_gate``, ``ray_fill_px``.

    Returns
    -------
    xyz : (n, 3) array
        The corrected positions (the estimate where no blob was found).
    n_rays : (n,) int array
        Rays that moved each field.
    used : int array
        Rows of ``spare`` taken.
    """
    n = len(prior)
    rows = spare.rows(first_field, first_field + n)
    none = np.zeros(n, dtype=np.int64), np.zeros(0, dtype=np.int64)
    if rows.size == 0 or not np.isfinite(prior_sd_mm) or prior_sd_mm <= 0:
        return prior.copy(), *none
    k = spare.field[rows] - first_field
    cam = spare.camera[rows]
    est = prior[k]
    dist = np.linalg.norm(project_rows(spare.dlts, cam, est) - spare.uv_px[rows], axis=1)
    pix = pixel_size_mm(spare.dlts, cam, est)
    gate = np.maximum(params.ray_fill_gate * prior_sd_mm / pix, 2.0 * params.ray_fill_px)
    take = _pick(k, cam, dist, gate, len(spare.dlts))
    if not take.any():
        return prior.copy(), *none
    rows, k, cam, pix = rows[take], k[take], cam[take], pix[take]
    d = ray_directions(spare.dlts[cam], spare.uv_px[rows])
    centre = spare.centres[cam]
    across = np.eye(3)[None] - d[:, :, None] * d[:, None, :]  # (m, 3, 3)
    w_ray = 1.0 / (params.ray_fill_px * pix) ** 2
    w_prior = 1.0 / prior_sd_mm**2
    m = np.broadcast_to(w_prior * np.eye(3), (n, 3, 3)).copy()
    b = w_prior * prior
    np.add.at(m, k, w_ray[:, None, None] * across)
    np.add.at(b, k, w_ray[:, None] * np.einsum("mij,mj->mi", across, centre))
    xyz = np.linalg.solve(m, b[:, :, None])[:, :, 0]
    return xyz, np.bincount(k, minlength=n), rows


def placed_errors(
    dense: NDArray, partners: NDArray, errors: NDArray | None, params: TrackingParams
) -> NDArray[np.float64]:
    """Each partner's own expected error per field (len(partners), n_fields): ``errors``'
    (0 where measured), ``ray_rest_max_error_mm`` where it holds a sample of unknown
    error; zeros without ``errors`` (every sample taken as measured). A chain fill on a
    placed partner inherits its error (lowcost seed 311: a toe on an ankle placed 3.8 mm
    off expecting 3.0 went 4.9 mm off expecting 2.1 as on a measured ankle)."""
    if errors is None:
        return np.zeros(dense.shape[:2])[partners]
    err = errors[partners]
    return np.where(np.isnan(err), params.ray_rest_max_error_mm, err)
