"""DLT parameters <-> conventional camera parameters (Woltring & Huiskes 1990, eq. 15).

The DLT matrix is ``P = K R [I | -C]`` up to scale, with ``K`` upper triangular
(principal distances in pixels along u and v, skew, principal point), ``R`` the
rotation lab -> camera (``x_cam = R (X - C)``, camera z along the optical axis, y down
the image) and ``C`` the projection centre in lab mm. This is eq. 15 of Woltring &
Huiskes with the camera z axis pointing forward instead of backward; the "orthogonal
triangularisation" they mention is the RQ decomposition used here.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from numpy.typing import ArrayLike, NDArray

from kisscal.dlt.model import dlt_from_krt, dlt_to_matrix


def decompose_matrix(
    P: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Split a 3 x 4 projection matrix into ``K`` (``K[2, 2] = 1``), ``R`` and centre.

    The overall sign is chosen so that ``K`` has a positive diagonal and ``R`` is a proper
    rotation; this recovers the true pose whatever the sign of the DLT normalisation
    ``P[2, 3] = 1`` (the lab origin may lie behind the camera).
    """
    P = np.asarray(P, dtype=float)
    M = P[:, :3]
    if np.linalg.det(M) < 0:
        P = -P
        M = P[:, :3]
    K, R = scipy.linalg.rq(M)
    D = np.diag(np.sign(np.diag(K)))
    K = K @ D
    R = D @ R
    centre = -np.linalg.solve(M, P[:, 3])
    return K / K[2, 2], R, centre


def decompose_dlt(
    L: ArrayLike,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Camera parameters of DLT parameters L1..L11 (Woltring & Huiskes 1990, eq. 15).

    Parameters
    ----------
    L : array_like, shape (11,)
        DLT parameters.

    Returns
    -------
    K : ndarray, shape (3, 3)
        ``[[fu, skew, u0], [0, fv, v0], [0, 0, 1]]`` in pixels (``fu``, ``fv`` > 0).
    R : ndarray, shape (3, 3)
        Rotation lab -> camera, ``det R = +1``.
    centre_mm : ndarray, shape (3,)
        Projection centre in lab mm.
    """
    return decompose_matrix(dlt_to_matrix(L))


def compose_dlt(K: ArrayLike, R: ArrayLike, centre_mm: ArrayLike) -> NDArray[np.float64]:
    """DLT parameters L1..L11 of ``K``, ``R`` and projection centre (inverse of decompose_dlt)."""
    R = np.asarray(R, dtype=float)
    return dlt_from_krt(K, R, -R @ np.asarray(centre_mm, dtype=float))


def hatze_violation(L: ArrayLike) -> float:
    """Relative violation of Hatze's orthogonality constraint (Kolahi et al. 2007, eq. 10).

    With ``a = (L1, L2, L3)``, ``b = (L5, L6, L7)``, ``c = (L9, L10, L11)`` the constraint
    is ``(a.c)(b.c) = (a.b)(c.c)``. The returned value is
    ``((a.c)(b.c) - (a.b)(c.c)) / (|a| |b| |c|^2)``, dimensionless; it equals
    ``-skew * fv / (|a| |b|)`` (with ``|a| = sqrt(fu^2 + skew^2 + u0^2)``,
    ``|b| = sqrt(fv^2 + v0^2)`` once ``|c| = 1``), so it vanishes exactly for a zero-skew
    camera and is of the order of ``skew / fu`` otherwise.
    """
    L = np.asarray(L, dtype=float)
    a, b, c = L[0:3], L[4:7], L[8:11]
    num = (a @ c) * (b @ c) - (a @ b) * (c @ c)
    return float(num / (np.linalg.norm(a) * np.linalg.norm(b) * (c @ c)))
