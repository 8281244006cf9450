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
