"""n-camera DLT triangulation with an iteratively reweighted step and reprojection RMS.

For a marker seen by n cameras the two DLT equations of each camera, multiplied out by the
denominator, are linear in (X, Y, Z): ``B X = D`` (Shafiq et al. 2001, eqs. 9-10; Küçük
2005, eq. 3.10). Their least-squares solution weighs each camera by its (unknown) depth
denominator, which biases it (Woltring & Huiskes 1990, sec. 3 and 10.1); dividing each
camera's equations by the denominator at the current estimate and solving again turns the
residuals into image distances, and two or three such steps converge.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points
from kisscal.errors import InputError

#: Observations triangulated in one block (the work arrays of a block fit the CPU cache).
_CHUNK = 1 << 15


@dataclass(frozen=True)
class Triangulation:
    """3D positions of points from their 2D observations.

    Attributes
    ----------
    xyz_mm : ndarray, shape (n_points, 3)
        Lab coordinates (mm); NaN where fewer than two cameras observed the point.
    rms_px : ndarray, shape (n_points,)
        Reprojection ``sqrt(mean(du^2 + dv^2))`` over the point's observations (px).
    n_cameras : ndarray of int, shape (n_points,)
        Number of observations used.
    residual_px : ndarray, shape (n_obs,)
        Euclidean reprojection error of each observation (px), in input order.
    """

    xyz_mm: NDArray[np.float64]
    rms_px: NDArray[np.float64]
    n_cameras: NDArray[np.int64]
    residual_px: NDArray[np.float64]


def _check_dlts(dlts: ArrayLike) -> NDArray[np.float64]:
    dlts = np.asarray(dlts, dtype=float)
    if dlts.ndim != 2 or dlts.shape[1] != 11:
        raise InputError(f"DLT parameters must have shape (n_cameras, 11), got {dlts.shape}")
    if not np.all(np.isfinite(dlts)):
        raise InputError("DLT parameters contain NaN or infinite values")
    return dlts


def triangulate_observations(
    dlts: ArrayLike,
    point: ArrayLike,
    camera: ArrayLike,
    uv: ArrayLike,
    n_points: int | None = None,
    reweight_iterations: int = 2,
) -> Triangulation:
    """Triangulate many points at once from long-format observations.

    Solves Shafiq et al. 2001 eq. 10, ``X = (B^T B)^-1 B^T D``, for every point in one batch
    (normal equations accumulated with ``bincount``), then ``reweight_iterations`` times
    re-solves with each camera's rows divided by its DLT denominator
    ``L9 X + L10 Y + L11 Z + 1`` at the current estimate (Woltring & Huiskes 1990, sec. 3).

    Parameters
    ----------
    dlts : array_like, shape (n_cameras, 11)
        DLT parameters L1..L11 of each camera (lab mm -> linearised px).
    point : array_like of int, shape (n_obs,)
        Point each observation belongs to (0 .. n_points - 1).
    camera : array_like of int, shape (n_obs,)
        Camera index (row of ``dlts``) of each observation.
    uv : array_like, shape (n_obs, 2)
        Linearised pixel coordinates.
    n_points : int, optional
        Number of points (default ``point.max() + 1``).
    reweight_iterations : int
        Reweighted steps after the linear solution.

    Returns
    -------
    Triangulation
    """
    dlts = _check_dlts(dlts)
    point = np.asarray(point, dtype=np.int64)
    camera = np.asarray(camera, dtype=np.int64)
    uv = as_points(uv, 2, "uv")
    if not (len(point) == len(camera) == len(uv)):
        raise InputError("point, camera and uv must have one row per observation")
    if n_points is None:
        n_points = int(point.max()) + 1 if len(point) else 0
    if len(point) <= _CHUNK:
        return _solve(dlts, point, camera, uv, n_points, reweight_iterations)
    # a large batch in blocks of points: its ~30 work arrays then stay in the CPU cache
    # (2x faster on 180k observations). Each point's sums run over its observations in
    # input order either way, so the results are bitwise those of one batch.
    order = None if np.all(point[1:] >= point[:-1]) else np.argsort(point, kind="stable")
    sorted_point = point if order is None else point[order]
    step = max(1, n_points * _CHUNK // len(point))
    starts = np.arange(0, n_points, step)
    cuts = np.r_[np.searchsorted(sorted_point, starts), len(point)]
    xyz = np.empty((n_points, 3))
    rms = np.empty(n_points)
    n_cameras = np.empty(n_points, dtype=np.int64)
    residual = np.empty(len(point))
    for p0, lo, hi in zip(starts.tolist(), cuts[:-1].tolist(), cuts[1:].tolist(), strict=True):
        obs = slice(lo, hi) if order is None else order[lo:hi]
        pts = slice(p0, min(p0 + step, n_points))
        part = _solve(
            dlts,
            sorted_point[lo:hi] - p0,
            camera[obs],
            uv[obs],
            pts.stop - p0,
            reweight_iterations,
        )
        xyz[pts], rms[pts] = part.xyz_mm, part.rms_px
        n_cameras[pts], residual[obs] = part.n_cameras, part.residual_px
    return Triangulation(xyz, rms, n_cameras, residual)


def _solve(
    dlts: NDArray[np.float64],
    point: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    n_points: int,
    reweight_iterations: int,
) -> Triangulation:
    """:func:`triangulate_observations` of one batch (checked arrays)."""
    L = np.take(dlts, camera, axis=0)  # (n_obs, 11); take is faster than fancy indexing
    u, v = uv[:, 0], uv[:, 1]
    lower = L[:, 8:11]
    a_u = L[:, 0:3] - u[:, None] * lower
    a_v = L[:, 4:7] - v[:, None] * lower
    b_u = u - L[:, 3]
    b_v = v - L[:, 7]
    n_cameras = np.bincount(point, minlength=n_points)
    solvable = n_cameras >= 2
    # per observation, the 6 distinct entries of the symmetric normal matrix and the 3 of
    # the right-hand side; they do not change between steps, only their weights do
    prods = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
    terms = [a_u[:, i] * a_u[:, j] + a_v[:, i] * a_v[:, j] for i, j in prods]
    terms += [a_u[:, i] * b_u + a_v[:, i] * b_v for i in range(3)]
    weighted = terms
    for step in range(reweight_iterations + 1):
        a, b, c, d, e, f, r0, r1, r2 = (np.bincount(point, t, n_points) for t in weighted)
        # closed-form inverse by cofactors: much faster than batched LAPACK for 3 x 3
        c00, c01, c02 = d * f - e * e, c * e - b * f, b * e - c * d
        c11, c12, c22 = a * f - c * c, b * c - a * e, a * d - b * b
        det = a * c00 + b * c01 + c * c02
        # a point seen along (nearly) one ray has a singular system: leave it NaN
        ok = solvable & (np.abs(det) > 1e-12 * ((a + d + f) / 3.0) ** 3)
        with np.errstate(invalid="ignore", divide="ignore"):
            inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), np.nan)
        xyz = np.column_stack(
            [
                (c00 * r0 + c01 * r1 + c02 * r2) * inv,
                (c01 * r0 + c11 * r1 + c12 * r2) * inv,
                (c02 * r0 + c12 * r1 + c22 * r2) * inv,
            ]
        )
        at_obs = xyz[point]
        denom = np.einsum("ij,ij->i", lower, at_obs) + 1.0  # also the projection's
        if step == reweight_iterations:
            break
        w2 = 1.0 / np.where(np.isfinite(denom) & (np.abs(denom) > 1e-12), denom, 1.0) ** 2
        weighted = [t * w2 for t in terms]
    # reprojection as :func:`~kisscal.dlt.model.project_rows` does it, on the rows above
    du = (np.einsum("ij,ij->i", L[:, 0:3], at_obs) + L[:, 3]) / denom - u
    dv = (np.einsum("ij,ij->i", L[:, 4:7], at_obs) + L[:, 7]) / denom - v
    sq = du * du + dv * dv
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(np.bincount(point, sq, n_points) / n_cameras)
    rms[~solvable] = np.nan
    return Triangulation(xyz, rms, n_cameras, np.sqrt(sq))


def triangulate(dlts: ArrayLike, uv: ArrayLike, reweight_iterations: int = 2) -> Triangulation:
    """Triangulate points given as a dense (point, camera) array with NaN where unseen.

    Parameters
    ----------
    dlts : array_like, shape (n_cameras, 11)
    uv : array_like, shape (n_points, n_cameras, 2)
        Linearised pixel coordinates; NaN marks a camera that did not see the point.
    reweight_iterations : int
        See :func:`triangulate_observations`.

    Returns
    -------
    Triangulation
        ``residual_px`` is in the row-major order of the observed (point, camera) cells.
    """
    dlts = _check_dlts(dlts)
    uv = np.asarray(uv, dtype=float)
    if uv.ndim != 3 or uv.shape[1:] != (len(dlts), 2):
        raise InputError(
            f"uv must have shape (n_points, {len(dlts)}, 2) for {len(dlts)} cameras, got {uv.shape}"
        )
    seen = np.all(np.isfinite(uv), axis=2)
    point, camera = np.nonzero(seen)
    return triangulate_observations(
        dlts, point, camera, uv[point, camera], len(uv), reweight_iterations
    )
