"""The 11-parameter linear DLT on Hartley-normalised coordinates.

Küçük 2005, section 2.3, eqs. 2.10-2.13 (and Kolahi et al. 2007, eqs. 4-9): each control
point gives two equations linear in L1..L11; at least six non-coplanar points are needed.
The system is solved on similarity-normalised coordinates (3D points centred and scaled
to a mean distance of sqrt(3), pixels to sqrt(2)) as a homogeneous least-squares problem
by SVD, then converted back to L1..L11 of lab mm and pixels (DESIGN.md).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import apply_transform, similarity_normaliser
from kisscal.dlt.model import matrix_to_dlt, project
from kisscal.dlt.params import DEFAULT_PARAMS, DltParams
from kisscal.errors import EstimationFailed, InputError


def check_control_points(
    xyz_mm: ArrayLike, uv_px: ArrayLike, params: DltParams = DEFAULT_PARAMS, camera: str = ""
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Validate control points for a DLT fit; return them as float arrays.

    Raises
    ------
    KisscalError
        Mismatched shapes, non-finite values, fewer than ``params.min_points`` points, or
        points (nearly) coplanar or collinear (``params.min_spread_ratio``).
    """
    where = f"camera {camera}: " if camera else ""
    xyz = np.asarray(xyz_mm, dtype=float)
    uv = np.asarray(uv_px, dtype=float)
    if xyz.ndim != 2 or xyz.shape[1] != 3 or uv.shape != (len(xyz), 2):
        raise InputError(
            f"{where}control points need xyz (N, 3) and uv (N, 2), got {xyz.shape} and {uv.shape}"
        )
    if not (np.isfinite(xyz).all() and np.isfinite(uv).all()):
        raise InputError(f"{where}control points contain NaN or infinite coordinates")
    if len(xyz) < params.min_points:
        raise EstimationFailed(
            f"{where}the 11-parameter DLT needs at least {params.min_points} control points, "
            f"got {len(xyz)}"
        )
    ratio = spread_ratio(xyz)
    if not ratio >= params.min_spread_ratio:
        raise EstimationFailed(
            f"{where}the {len(xyz)} control points are coplanar (thickness/extent "
            f"{ratio:.1e} < {params.min_spread_ratio:g}); the DLT needs a 3D distribution"
        )
    return xyz, uv


def spread_ratio(xyz_mm: ArrayLike) -> float:
    """Least over largest principal spread of 3D points: 0 for coplanar or collinear points.

    The one coplanarity measure of kisscal: configurations below
    ``DltParams.min_spread_ratio`` cannot determine an 11-parameter DLT.
    """
    xyz = np.asarray(xyz_mm, dtype=float)
    spread = np.linalg.svd(xyz - xyz.mean(axis=0), compute_uv=False)
    return float(spread[2] / spread[0]) if spread[0] > 0 else 0.0


def solve_dlt_matrix(
    xyz: NDArray[np.float64], uv: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Linear DLT on normalised coordinates (no input checks).

    Returns ``(Pn, T3, T2, singular_values)`` where ``Pn`` (3 x 4) maps normalised 3D to
    normalised 2D, ``P = inv(T2) Pn T3`` maps lab mm to pixels.
    """
    T3 = similarity_normaliser(xyz)
    T2 = similarity_normaliser(uv)
    X = np.hstack([apply_transform(T3, xyz), np.ones((len(xyz), 1))])
    u = apply_transform(T2, uv)
    n = len(xyz)
    A = np.zeros((2 * n, 12))
    A[0::2, 0:4] = X
    A[0::2, 8:12] = -u[:, :1] * X
    A[1::2, 4:8] = X
    A[1::2, 8:12] = -u[:, 1:2] * X
    _, s, vt = np.linalg.svd(A, full_matrices=False)
    return vt[-1].reshape(3, 4), T3, T2, s


def solve_dlt(
    xyz_mm: ArrayLike, uv_px: ArrayLike, params: DltParams = DEFAULT_PARAMS, camera: str = ""
) -> NDArray[np.float64]:
    """Linear 11-parameter DLT (Küçük 2005, eqs. 2.10-2.13) on Hartley-normalised data.

    Parameters
    ----------
    xyz_mm : array_like, shape (N, 3)
        Control points in lab mm, N >= 6, not coplanar.
    uv_px : array_like, shape (N, 2)
        Their (linearised) image coordinates in pixels.
    params : DltParams
        ``min_points`` and ``min_spread_ratio`` are used.
    camera : str
        Camera id, named in error messages.

    Returns
    -------
    ndarray, shape (11,)
        L1..L11.

    Raises
    ------
    KisscalError
        Degenerate input (see :func:`check_control_points`) or a rank-deficient system.
    """
    xyz, uv = check_control_points(xyz_mm, uv_px, params, camera)
    Pn, T3, T2, s = solve_dlt_matrix(xyz, uv)
    if s[-2] < 1e-10 * s[0]:
        raise EstimationFailed(
            f"camera {camera}: the control points do not determine the DLT (rank-deficient)"
        )
    P = np.linalg.solve(T2, Pn @ T3)
    try:
        return matrix_to_dlt(P)
    except ValueError as exc:
        raise EstimationFailed(f"camera {camera}: {exc}") from exc


def reprojection_residuals(
    L: ArrayLike, xyz_mm: ArrayLike, uv_px: ArrayLike
) -> NDArray[np.float64]:
    """Observed minus projected pixel coordinates ``(du, dv)``, shape (N, 2)."""
    return np.asarray(uv_px, dtype=float) - project(L, xyz_mm)
