"""The camera model of the bundle adjustment: pinhole, Brown lens, and its exchange forms.

A camera maps a lab point ``X`` (mm) to pixels by ``x = R X + t`` (camera frame, z along
the optical axis), ``(xn, yn) = (x1 / x3, x2 / x3)``, Brown's lens distortion on those
normalised coordinates (Brown 1971, in OpenCV's convention: radial ``k1 k2 k3``,
decentring ``p1 p2``) and the intrinsic matrix ``K = [[fu, s, u0], [0, fv, v0], [0, 0, 1]]``
(principal distances in pixels along u and v, hence the pixel aspect, the skew ``s`` and
the principal point). Without distortion this is the DLT camera ``P = K [R | t]``
(Woltring & Huiskes 1990, eq. 15).

Cameras are exchanged with the rest of kisscal as a DLT (L1..L11) plus a 4th-order
linearisation polynomial (Küçük 2005, eq. 2.2) that takes raw pixels to the distortion-free
pixels ``K (xn, yn, 1)``: :func:`camera_linearisation` fits its 30 coefficients over the
whole image.

References
----------
Brown, D. C. (1971). Close-range camera calibration. Photogrammetric Engineering 37(8).
Woltring, H. J., & Huiskes, R. (1990). Stereophotogrammetry. In Biomechanics of Human
Movement (Berme & Cappozzo, eds.).
Küçük, M. (2005). Calibration and 3D reconstruction for the KISS gait laboratory (thesis).
Lawson, C. L. (1961). Contributions to the theory of linear least maximum approximation
(thesis, University of California, Los Angeles).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from kisscal.dlt.camera import decompose_dlt
from kisscal.dlt.model import dlt_from_krt
from kisscal.grid.poly import Linearisation, apply_linearisation, fit_polynomial

_LAWSON_ROUNDS = 8
#: Brown lens terms, in the order of OpenCV's distortion vector.
LENS_TERMS: tuple[str, ...] = ("k1", "k2", "p1", "p2", "k3")


@dataclass(frozen=True, eq=False)
class PinholeCamera:
    """One camera of the bundle adjustment.

    Attributes
    ----------
    K : ndarray, shape (3, 3)
        Intrinsic matrix (``K[2, 2] = 1``), pixels.
    R : ndarray, shape (3, 3)
        Rotation lab -> camera.
    t : ndarray, shape (3,)
        Translation (mm): ``x_cam = R X + t``.
    lens : ndarray, shape (5,)
        Brown terms ``k1 k2 p1 p2 k3`` on normalised coordinates.
    """

    K: NDArray[np.float64]
    R: NDArray[np.float64]
    t: NDArray[np.float64]
    lens: NDArray[np.float64]

    @property
    def centre_mm(self) -> NDArray[np.float64]:
        """Projection centre in lab mm."""
        return -self.R.T @ self.t

    @property
    def dlt(self) -> NDArray[np.float64]:
        """L1..L11 of the distortion-free camera (lab mm -> linearised pixels)."""
        return dlt_from_krt(self.K, self.R, self.t)

    def project(self, xyz_mm: ArrayLike) -> NDArray[np.float64]:
        """Raw (distorted) pixel coordinates of lab points, shape (n, 2)."""
        xyz = np.asarray(xyz_mm, dtype=float).reshape(-1, 3)
        xc = xyz @ self.R.T + self.t
        xn = xc[:, :2] / xc[:, 2:3]
        return normalised_to_px(self.K[None], distort(self.lens[None], xn))

    def transformed(self, rotation: ArrayLike, shift_mm: ArrayLike) -> PinholeCamera:
        """This camera after the lab frame changes by ``X' = rotation X + shift_mm``."""
        Q = np.asarray(rotation, dtype=float)
        R = self.R @ Q.T
        return PinholeCamera(self.K, R, self.t - R @ np.asarray(shift_mm, dtype=float), self.lens)


def camera_from_dlt(L: ArrayLike, lens: ArrayLike | None = None) -> PinholeCamera:
    """The pinhole camera of DLT parameters (Woltring & Huiskes 1990, eq. 15)."""
    K, R, centre = decompose_dlt(L)
    lens_terms = np.zeros(len(LENS_TERMS)) if lens is None else np.asarray(lens, dtype=float)
    return PinholeCamera(K, R, -R @ centre, lens_terms)


def distort(lens: NDArray[np.float64], xn: NDArray[np.float64]) -> NDArray[np.float64]:
    """Brown's distortion of normalised coordinates, one lens per row (or one for all).

    Parameters
    ----------
    lens : ndarray, shape (n, 5) or (1, 5)
        ``k1 k2 p1 p2 k3`` of each row's camera.
    xn : ndarray, shape (n, 2)
        Undistorted normalised coordinates.

    Returns
    -------
    ndarray, shape (n, 2)
        ``x (1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x y + p2 (r² + 2 x²)`` and
        ``y (1 + k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2 y²) + 2 p2 x y``.
    """
    x, y = xn[:, 0], xn[:, 1]
    k1, k2, p1, p2, k3 = (lens[:, i] for i in range(5))
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
    yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
    return np.column_stack([xd, yd])


def distortion_jacobian(lens: NDArray[np.float64], xn: NDArray[np.float64]) -> NDArray[np.float64]:
    """``d(xd, yd) / d(x, y)`` of :func:`distort`, shape (n, 2, 2)."""
    x, y = xn[:, 0], xn[:, 1]
    k1, k2, p1, p2, k3 = (lens[:, i] for i in range(5))
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    d_radial = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3)
    D = np.empty((len(xn), 2, 2))
    D[:, 0, 0] = radial + 2 * x * x * d_radial + 2 * p1 * y + 6 * p2 * x
    D[:, 0, 1] = 2 * x * y * d_radial + 2 * p1 * x + 2 * p2 * y
    D[:, 1, 0] = D[:, 0, 1]
    D[:, 1, 1] = radial + 2 * y * y * d_radial + 6 * p1 * y + 2 * p2 * x
    return D


def undistort(
    lens: NDArray[np.float64], xd: NDArray[np.float64], tol: float = 1e-13
) -> NDArray[np.float64]:
    """Inverse of :func:`distort` for one lens (shape (1, 5)), by Newton's method."""
    x = xd.copy()
    for _ in range(50):
        err = distort(lens, x) - xd
        D = distortion_jacobian(lens, x)
        det = D[:, 0, 0] * D[:, 1, 1] - D[:, 0, 1] * D[:, 1, 0]
        step = np.column_stack(
            [
                (D[:, 1, 1] * err[:, 0] - D[:, 0, 1] * err[:, 1]) / det,
                (D[:, 0, 0] * err[:, 1] - D[:, 1, 0] * err[:, 0]) / det,
            ]
        )
        x -= step
        if not len(x) or np.max(np.abs(step)) < tol:
            break
    return x


def normalised_to_px(K: NDArray[np.float64], xn: NDArray[np.float64]) -> NDArray[np.float64]:
    """Pixels of normalised coordinates, one ``K`` per row (or one for all), shape (n, 2)."""
    u = K[:, 0, 0] * xn[:, 0] + K[:, 0, 1] * xn[:, 1] + K[:, 0, 2]
    v = K[:, 1, 1] * xn[:, 1] + K[:, 1, 2]
    return np.column_stack([u, v])


def px_to_normalised(K: NDArray[np.float64], uv: NDArray[np.float64]) -> NDArray[np.float64]:
    """Normalised coordinates of pixels under one intrinsic matrix, shape (n, 2)."""
    y = (uv[:, 1] - K[1, 2]) / K[1, 1]
    x = (uv[:, 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
    return np.column_stack([x, y])


def undistort_px(camera: PinholeCamera, uv_px: ArrayLike) -> NDArray[np.float64]:
    """Distortion-free pixels ``K (xn, yn, 1)`` of raw pixels (inverse of the lens)."""
    uv = np.asarray(uv_px, dtype=float).reshape(-1, 2)
    xd = px_to_normalised(camera.K, uv)
    if np.any(camera.lens):
        xd = undistort(camera.lens[None], xd)
    return normalised_to_px(camera.K[None], xd)


def camera_linearisation(
    camera: PinholeCamera,
    size_px: tuple[int, int],
    before: Linearisation | None = None,
    data_px: ArrayLike | None = None,
    samples: int = 25,
    lattice_weight: float = 0.1,
    minimax: bool = False,
) -> tuple[Linearisation, float]:
    """The 30-coefficient polynomial taking raw pixels to the camera's distortion-free pixels.

    A fourth-order polynomial cannot follow a lens model exactly. The least-squares fit
    is weighted where it matters, on the raw image positions the camera was calibrated
    from (``data_px``), with a ``samples`` x ``samples`` lattice over the whole image
    (corners included) carrying ``lattice_weight`` of their total weight so the
    polynomial stays faithful where there were none. With ``minimax`` (for a polynomial
    that is the whole lens model, without a grid's before it) Lawson's reweighting
    (Lawson 1961) then spreads the error evenly, which brings the image corners to about
    a third of the least-squares error there, for a little more inside.

    Parameters
    ----------
    camera : PinholeCamera
        Its lens acts on the coordinates ``before`` produces (raw pixels if None).
    size_px : (int, int)
        Image width and height.
    before : Linearisation, optional
        A linearisation applied first (a grid's), composed with the lens inverse.
    data_px : array_like, shape (n, 2), optional
        Raw positions of the observations (default: the lattice alone).
    samples : int
        Lattice points per side.
    lattice_weight : float
        The lattice's share of the data's weight.
    minimax : bool
        Spread the largest errors evenly (Lawson's iteratively reweighted least squares).

    Returns
    -------
    lin : Linearisation
        Normalised on the image centre and half the larger side (as the grid stage does).
    fit_max_px : float
        Largest distance between the polynomial and the exact map over the lattice (px).
    """
    w, h = size_px
    u, v = np.meshgrid(np.linspace(-0.5, w - 0.5, samples), np.linspace(-0.5, h - 0.5, samples))
    lattice = np.column_stack([u.ravel(), v.ravel()])
    data = np.zeros((0, 2)) if data_px is None else np.asarray(data_px, dtype=float).reshape(-1, 2)
    raw = np.concatenate([lattice, data])
    share = lattice_weight * len(data) / len(lattice) if len(data) else 1.0
    weights = np.r_[np.full(len(lattice), share), np.ones(len(data))]
    mid = raw if before is None else apply_linearisation(before, raw)
    target = undistort_px(camera, mid)
    centre, scale = ((w - 1) / 2.0, (h - 1) / 2.0), max(w, h) / 2.0
    for _ in range(_LAWSON_ROUNDS if minimax else 1):
        lin = fit_polynomial(raw, target, centre, scale, weights)
        err = np.linalg.norm(apply_linearisation(lin, raw) - target, axis=1)
        weights = weights * (err + 1e-12)
        weights /= weights.mean()
    return lin, float(err[: len(lattice)].max())


def rotation_matrices(rotvec: NDArray[np.float64]) -> NDArray[np.float64]:
    """Rotation matrices of rotation vectors, shape (n, 3, 3)."""
    return Rotation.from_rotvec(np.asarray(rotvec, dtype=float).reshape(-1, 3)).as_matrix()
