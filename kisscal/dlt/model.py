"""The DLT camera model: projection with L1..L11 and composition from K, R, t.

Convention (Abdel-Aziz & Karara, DESIGN.md)::

    u = (L1 X + L2 Y + L3 Z + L4) / (L9 X + L10 Y + L11 Z + 1)
    v = (L5 X + L6 Y + L7 Z + L8) / (L9 X + L10 Y + L11 Z + 1)

which is the 3 x 4 projection matrix ``P = K [R | t]`` scaled so that ``P[2, 3] = 1``
(Woltring & Huiskes 1990, eq. 15).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points
from kisscal.errors import EstimationFailed, InputError


def dlt_to_matrix(L: ArrayLike) -> NDArray[np.float64]:
    """Return the 3 x 4 projection matrix of DLT parameters L1..L11 (with ``P[2, 3] = 1``)."""
    L = np.asarray(L, dtype=float)
    if L.shape != (11,):
        raise ValueError(f"DLT parameters must have shape (11,), got {L.shape}")
    return np.append(L, 1.0).reshape(3, 4)


def matrix_to_dlt(P: ArrayLike) -> NDArray[np.float64]:
    """Return L1..L11 of a 3 x 4 projection matrix, normalised so that ``P[2, 3] = 1``.

    ``P[2, 3]`` is the depth of the lab origin in the camera frame; it is zero only when
    the lab origin lies in the camera's focal plane, which a lab set-up never does.
    """
    P = np.asarray(P, dtype=float)
    if P.shape != (3, 4):
        raise ValueError(f"projection matrix must have shape (3, 4), got {P.shape}")
    if abs(P[2, 3]) < 1e-12 * np.abs(P).max():
        raise ValueError("the lab origin lies in the camera's focal plane; DLT form undefined")
    return (P / P[2, 3]).ravel()[:11].copy()


def dlt_from_krt(K: ArrayLike, R: ArrayLike, t: ArrayLike) -> NDArray[np.float64]:
    """DLT parameters of a pinhole camera ``x_cam = R X + t``, pixels ``K x_cam``."""
    K = np.asarray(K, dtype=float)
    R = np.asarray(R, dtype=float)
    t = np.asarray(t, dtype=float).reshape(3, 1)
    return matrix_to_dlt(K @ np.hstack([R, t]))


def project(L: ArrayLike, xyz_mm: ArrayLike) -> NDArray[np.float64]:
    """Project lab points through DLT parameters.

    Parameters
    ----------
    L : array_like, shape (11,)
        DLT parameters L1..L11.
    xyz_mm : array_like, shape (..., 3)
        Lab coordinates in millimetres.

    Returns
    -------
    ndarray, shape (..., 2)
        Image coordinates ``(u, v)`` in pixels.
    """
    P = dlt_to_matrix(L)
    xyz = np.asarray(xyz_mm, dtype=float)
    h = xyz @ P[:, :3].T + P[:, 3]
    return h[..., :2] / h[..., 2:3]


def project_rows(dlts: ArrayLike, camera: ArrayLike, xyz_mm: ArrayLike) -> NDArray[np.float64]:
    """Project point ``k`` into camera ``camera[k]``, for many (camera, point) rows at once.

    Parameters
    ----------
    dlts : array_like, shape (n_cameras, 11)
        DLT parameters of every camera.
    camera : array_like of int, shape (n,)
        Camera (row of ``dlts``) of each row.
    xyz_mm : array_like, shape (n, 3)
        Lab point of each row.

    Returns
    -------
    ndarray, shape (n, 2)
        Image coordinates ``(u, v)`` in pixels.

    Examples
    --------
    >>> import numpy as np
    >>> L = np.array([[1.0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0]] * 2)
    >>> project_rows(L, [0, 1], [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    array([[1., 2.],
           [4., 5.]])
    """
    L = np.asarray(dlts, dtype=float)[np.asarray(camera, dtype=np.int64)]
    xyz = as_points(xyz_mm, 3, "xyz_mm")
    den = np.einsum("ij,ij->i", L[:, 8:11], xyz) + 1.0
    u = (np.einsum("ij,ij->i", L[:, 0:3], xyz) + L[:, 3]) / den
    v = (np.einsum("ij,ij->i", L[:, 4:7], xyz) + L[:, 7]) / den
    return np.column_stack([u, v])


def pixel_size_mm(dlts: ArrayLike, camera: ArrayLike, xyz_mm: ArrayLike) -> NDArray[np.float64]:
    """The size (mm) one pixel of camera ``camera[k]`` spans at lab point ``k``.

    The projection's Jacobian (2 x 3, from central differences of 1 mm) has two non-zero
    singular values, pixels per mm across the ray; the pixel size is the inverse of their
    geometric mean (about depth / focal length). It turns an image residual (px) into
    the C3D standard's residual in point units.

    Examples
    --------
    >>> import numpy as np
    >>> from kisscal.dlt.model import dlt_from_krt
    >>> K = np.array([[1000.0, 0, 320], [0, 1000.0, 240], [0, 0, 1]])
    >>> L = dlt_from_krt(K, np.eye(3), [0.0, 0.0, 1000.0])[None]  # origin 1 m ahead
    >>> pixel_size_mm(L, [0], [[0.0, 0.0, 1000.0]]).round(3)  # a point 2 m ahead
    array([2.])
    """
    xyz = as_points(xyz_mm, 3, "xyz_mm")
    camera = np.asarray(camera, dtype=np.int64)
    steps = np.eye(3)
    jac = (
        np.stack(
            [
                project_rows(dlts, camera, xyz + d) - project_rows(dlts, camera, xyz - d)
                for d in steps
            ],
            axis=2,
        )
        / 2.0
    )  # (n, 2, 3): px per mm
    sv = np.linalg.svd(jac, compute_uv=False)
    return 1.0 / np.sqrt(np.maximum(sv[:, 0] * sv[:, 1], 1e-300))


def ray_directions(L: NDArray, uv: NDArray) -> NDArray[np.float64]:
    """Unit direction (n, 3) of the ray of pixel ``uv[k]`` of DLT ``L[k]``: the line where
    the two planes ``(L1 - u L9) . x = u - L4`` and ``(L5 - v L9) . x = v - L8`` meet."""
    a1 = L[:, 0:3] - uv[:, :1] * L[:, 8:11]
    a2 = L[:, 4:7] - uv[:, 1:] * L[:, 8:11]
    d = np.cross(a1, a2)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def line_offsets(rel: NDArray, d: NDArray) -> tuple[NDArray, NDArray]:
    """Where points lie along a line and how far off it: for offsets ``rel`` (..., 3) of
    points from a point of the line and its unit direction ``d`` (broadcast against
    ``rel``), the position along ``d`` and the distance from the line (both (...))."""
    along = np.einsum("...j,...j->...", rel, d)
    return along, np.linalg.norm(rel - along[..., None] * d, axis=-1)


def ray_points(
    dlts: NDArray[np.float64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    target: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Per row, the point of the ray of blob ``uv`` in ``camera`` nearest to ``target``:
    the ray is where both DLT equations ``(L1 - u L9) . X + L4 - u = 0`` and
    ``(L5 - v L9) . X + L8 - v = 0`` hold."""
    L = dlts[camera]
    u, v = uv[:, 0:1], uv[:, 1:2]
    A = np.stack([L[:, 0:3] - u * L[:, 8:11], L[:, 4:7] - v * L[:, 8:11]], axis=1)
    rhs = np.stack([uv[:, 0] - L[:, 3], uv[:, 1] - L[:, 7]], axis=1)
    r = np.einsum("nij,nj->ni", A, target) - rhs
    g = np.einsum("nij,nkj->nik", A, A)
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = np.linalg.solve(g, r[..., None])[..., 0]
    return target - np.einsum("nij,ni->nj", A, lam)


def camera_centre_mm(L: ArrayLike) -> NDArray[np.float64]:
    """Projection centre (mm) of a DLT camera: the null vector of ``P = [M | p4]``.

    Parameters
    ----------
    L : array_like, shape (11,)
        DLT parameters L1..L11.

    Returns
    -------
    ndarray, shape (3,)
        ``-M^-1 p4`` in lab millimetres.
    """
    P = dlt_to_matrix(L)
    try:
        return -np.linalg.solve(P[:, :3], P[:, 3])
    except np.linalg.LinAlgError as exc:
        raise EstimationFailed("DLT parameters are degenerate: no projection centre") from exc


def _skew(e: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.array([[0.0, -e[2], e[1]], [e[2], 0.0, -e[0]], [-e[1], e[0], 0.0]])


def fundamental_from_dlt(L_i: ArrayLike, L_j: ArrayLike) -> NDArray[np.float64]:
    """Fundamental matrix of two DLT cameras, ``x_j^T F x_i = 0``.

    ``F = [e_j]_x M_j M_i^-1`` with ``e_j = P_j C_i`` the epipole of camera ``i`` in camera
    ``j``; the epipolar line of pixel ``(u_i, v_i)`` in camera ``j`` is ``F (u_i, v_i, 1)``,
    which expands to Shafiq et al. 2001 eq. 8 (coefficients bilinear in the source point).
    Scaled to unit Frobenius norm (point-line distances do not depend on the scale).

    Parameters
    ----------
    L_i, L_j : array_like, shape (11,)
        DLT parameters of the source and target cameras.

    Returns
    -------
    ndarray, shape (3, 3)
    """
    P_i = dlt_to_matrix(L_i)
    P_j = dlt_to_matrix(L_j)
    C_i = np.append(camera_centre_mm(L_i), 1.0)
    e_j = P_j @ C_i
    if np.linalg.norm(e_j) <= 1e-9 * np.linalg.norm(P_j) * np.linalg.norm(C_i):
        raise InputError("two cameras share a projection centre: no epipolar geometry")
    F = _skew(e_j) @ P_j[:, :3] @ np.linalg.inv(P_i[:, :3])
    return F / np.linalg.norm(F)


def shift_dlt_pixels(L: ArrayLike, offset_px: ArrayLike) -> NDArray[np.float64]:
    """DLT parameters for pixel coordinates shifted by ``offset_px``: ``u' = u + du``,
    ``v' = v + dv`` (e.g. ``(1, 1)`` for tools whose first pixel's centre is (1, 1)).

    Exact: the shift moves ``du`` times the denominator row into the ``u`` row.

    Examples
    --------
    >>> L = dlt_from_krt(np.diag([800.0, 800, 1]), np.eye(3), [0, 0, 3000.0])
    >>> project(shift_dlt_pixels(L, (1, 1)), [10.0, 20, 0]) - project(L, [10.0, 20, 0])
    array([1., 1.])
    """
    P = dlt_to_matrix(L)
    du, dv = np.asarray(offset_px, dtype=float)
    P[0] += du * P[2]
    P[1] += dv * P[2]
    return matrix_to_dlt(P)
