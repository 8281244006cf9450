"""A calibrated camera in OpenCV's model and back: what anipose, Pose2Sim and OpenCV read.

OpenCV's camera (Bradski 2000; Brown 1966 distortion) is a zero-skew pinhole ``K [R | t]``
whose normalised image coordinates are distorted by ``k1 k2 k3`` (radial) and ``p1 p2``
(tangential) before ``K``. kisscal's camera is the 11-parameter DLT (any skew, Abdel-Aziz &
Karara 1971) on pixel coordinates linearised by a 30-coefficient polynomial (Küçük 2005).
The two models differ: :func:`opencv_from_camera` fits OpenCV's to kisscal's so that their
projections of the same lab points land as close as they can, over the whole image, and
reports what is left; :func:`camera_from_opencv` goes the other way (the DLT of ``K [R | t]``
and a polynomial fitted to OpenCV's undistortion).

Both models project through the same centre (``translation = -R C``), so the fit is one
of directions: the rays through a grid of raw pixels covering the image.

References
----------
Abdel-Aziz, Y. I., & Karara, H. M. (1971). Direct linear transformation from comparator
coordinates into object space coordinates in close-range photogrammetry.
Bradski, G. (2000). The OpenCV library. Dr. Dobb's Journal of Software Tools.
Brown, D. C. (1966). Decentering distortion of lenses. Photogrammetric Engineering.
Küçük, M. (2005). Calibration and 3D reconstruction for the KISS gait laboratory (thesis).

Examples
--------
>>> import numpy as np
>>> from kisscal.dlt.model import dlt_from_krt
>>> from kisscal.rig import Camera
>>> K = np.array([[800.0, 0, 319.5], [0, 780, 239.5], [0, 0, 1]])
>>> cam = Camera("c1", dlt_from_krt(K, np.eye(3), [0, 0, 3000.0]), size_px=(640, 480))
>>> fit = opencv_from_camera(cam)
>>> bool(fit.rms_px < 1e-6), np.round(fit.camera.matrix[0, 0], 3)
(True, np.float64(800.0))
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from kisscal.dlt.camera import decompose_dlt
from kisscal.dlt.model import dlt_from_krt
from kisscal.errors import KisscalError
from kisscal.grid.poly import Linearisation, apply_linearisation, fit_polynomial
from kisscal.rig import Camera

#: Raw pixels per side of the grid over which the models are fitted and compared.
GRID_STEP_PX = 12.0


@dataclass(frozen=True)
class OpenCvCamera:
    """One camera in OpenCV's model (the anipose / Pose2Sim ``cameras.toml`` table).

    Attributes
    ----------
    name : str
    size_px : (int, int)
        Width, height.
    matrix : ndarray, shape (3, 3)
        ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``, px; the principal point in OpenCV's
        (and kisscal's) pixel convention: the top-left pixel's centre is (0, 0).
    distortions : ndarray, shape (5,), (8,) or (12,)
        ``k1 k2 p1 p2 k3``, then the rational model's ``k4 k5 k6`` and the thin prism's
        ``s1 s2 s3 s4`` when fitted (OpenCV's order).
    rotation : ndarray, shape (3,)
        Rodrigues vector of ``R`` (lab -> camera).
    translation_mm : ndarray, shape (3,)
        ``t`` in ``x_cam = R X + t``.
    """

    name: str
    size_px: tuple[int, int]
    matrix: NDArray[np.float64]
    distortions: NDArray[np.float64]
    rotation: NDArray[np.float64]
    translation_mm: NDArray[np.float64]

    def project(self, xyz_mm: ArrayLike) -> NDArray[np.float64]:
        """Lab points -> raw pixels, with ``cv2.projectPoints``; shape (n, 2)."""
        xyz = np.asarray(xyz_mm, dtype=float).reshape(-1, 1, 3)
        uv, _ = cv2.projectPoints(
            xyz, self.rotation, self.translation_mm, self.matrix, self.distortions
        )
        return uv.reshape(-1, 2)


@dataclass(frozen=True)
class OpenCvFit:
    """An OpenCV camera fitted to a kisscal camera, and how close it lands.

    Attributes
    ----------
    camera : OpenCvCamera
    rms_px, max_px : float
        RMS (``sqrt(mean(du² + dv²))``) and largest distance between the two models'
        projections over a grid of raw pixels covering the image.
    skew_px : float
        The DLT's skew ``K[0, 1]`` (px), which OpenCV's matrix cannot hold.
    """

    camera: OpenCvCamera
    rms_px: float
    max_px: float
    skew_px: float


def image_grid(size_px: tuple[int, int], step_px: float = GRID_STEP_PX) -> NDArray[np.float64]:
    """Raw pixel positions covering the whole image, corners included, shape (n, 2)."""
    w, h = size_px
    u = np.linspace(-0.5, w - 0.5, max(round(w / step_px), 2) + 1)
    v = np.linspace(-0.5, h - 0.5, max(round(h / step_px), 2) + 1)
    return np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)


def _padded(d: NDArray[np.float64]) -> NDArray[np.float64]:
    """Any of OpenCV's distortion vectors (4, 5, 8 or 12 numbers) as all 12."""
    return np.r_[np.asarray(d, dtype=float).ravel(), np.zeros(12)][:12]


def _distort(xy: NDArray[np.float64], d: NDArray[np.float64]) -> NDArray[np.float64]:
    """OpenCV's distortion of normalised coordinates, vectorised: ``k1 k2 p1 p2 k3``, then
    the rational model's ``k4 k5 k6`` and the thin prism's ``s1 s2 s3 s4`` when given."""
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = _padded(d)
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    radial = (1 + r2 * (k1 + r2 * (k2 + r2 * k3))) / (1 + r2 * (k4 + r2 * (k5 + r2 * k6)))
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x) + r2 * (s1 + s2 * r2)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y + r2 * (s3 + s4 * r2)
    return np.stack([xd, yd], axis=-1)


def _project(theta: NDArray[np.float64], rays: NDArray[np.float64]) -> NDArray[np.float64]:
    """Pixels of camera-centred lab directions under parameters ``theta``:
    Rodrigues (3), fx, fy, cx, cy, then the distortion vector (5, 8 or 12)."""
    R = cv2.Rodrigues(theta[0:3])[0]
    pc = rays @ R.T
    xy = _distort(pc[:, :2] / pc[:, 2:3], theta[7:])
    return xy * theta[3:5] + theta[5:7]


def rim_weights(
    raw: NDArray[np.float64], size_px: tuple[int, int], fraction: float, weight: float
) -> NDArray[np.float64]:
    """Weight of each fit position: ``weight`` within ``fraction`` of the image's smaller
    side from its border, 1 inside."""
    w, h = size_px
    m = fraction * min(w, h)
    u, v = raw[:, 0] + 0.5, raw[:, 1] + 0.5
    inner = (u > m) & (u < w - m) & (v > m) & (v < h - m)
    return np.where(inner, 1.0, weight)


def opencv_from_camera(
    camera: Camera,
    step_px: float = GRID_STEP_PX,
    coefficients: int = 12,
    rim_fraction: float = 0.08,
    rim_weight: float = 0.1,
    *,
    k3: bool = True,
) -> OpenCvFit:
    """OpenCV's model fitted to a kisscal camera: matrix, distortions and rotation by
    least squares (Levenberg-Marquardt) on the rays through a grid of raw pixels covering
    the image; the centre is the DLT's (Woltring & Huiskes 1990, eq. 15).

    ``coefficients`` is the length of the distortion vector: 5 (``k1 k2 p1 p2 k3``),
    8 (with the rational model's ``k4 k5 k6``) or 12 (and the thin prism's ``s1..s4``).
    OpenCV's functions, and so anipose and Pose2Sim, accept all three; 12 follows a
    grid's 4th-order polynomial best (a third to a half of the 5-term model's 3D error
    on the synthetic rigs). The image's rim (``rim_fraction`` of its smaller side)
    counts ``rim_weight`` as much as its inside: there the polynomial extrapolates
    beyond the grid's dots, and no model follows it there without giving up the inside,
    where the measurements are.

    ``k3`` False holds the third radial term at 0 (with ``coefficients=5``): the four
    coefficients ``k1 k2 p1 p2`` that Pose2Sim writes and reads.

    Raises
    ------
    KisscalError
        When the camera's image size is unknown, or ``coefficients`` is not 5, 8 or 12.
    """
    if camera.size_px is None:
        raise KisscalError(f"camera {camera.id}: image size unknown; cannot fit OpenCV's model")
    if coefficients not in (5, 8, 12):
        raise KisscalError(f"OpenCV distortion coefficients must be 5, 8 or 12, got {coefficients}")
    K, R, centre = decompose_dlt(camera.L)
    raw = image_grid(camera.size_px, step_px)
    weight = np.sqrt(rim_weights(raw, camera.size_px, rim_fraction, rim_weight))[:, None]
    uv = camera.linearise(raw)
    rays = np.c_[uv, np.ones(len(uv))] @ np.linalg.inv(K).T @ R  # lab directions, forward
    rvec = cv2.Rodrigues(R)[0].ravel()
    theta0 = np.r_[rvec, K[0, 0], K[1, 1], K[0, 2], K[1, 2], np.zeros(coefficients)]
    free = np.ones(theta0.size, dtype=bool)
    free[11] = k3  # theta[11] is k3 (distortions start at theta[7]: k1 k2 p1 p2 k3 ...)

    def residuals(x: NDArray[np.float64]) -> NDArray[np.float64]:
        th = theta0.copy()
        th[free] = x
        return ((_project(th, rays) - raw) * weight).ravel()

    th = theta0.copy()
    th[free] = least_squares(residuals, theta0[free], method="lm", x_scale="jac").x
    R_fit = cv2.Rodrigues(th[0:3])[0]
    matrix = np.array([[th[3], 0.0, th[5]], [0.0, th[4], th[6]], [0.0, 0.0, 1.0]])
    cv = OpenCvCamera(
        camera.id, tuple(camera.size_px), matrix, th[7:].copy(), th[0:3].copy(), -R_fit @ centre
    )
    d = np.hypot(*(_project(th, rays) - raw).T)
    return OpenCvFit(cv, float(np.sqrt(np.mean(d**2))), float(d.max()), float(K[0, 1]))


def _distort_jacobian(xy: NDArray[np.float64], d: NDArray[np.float64]) -> NDArray[np.float64]:
    """d(xd, yd) / d(x, y) of :func:`_distort`, shape (n, 2, 2)."""
    k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = _padded(d)
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    num = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    den = 1 + r2 * (k4 + r2 * (k5 + r2 * k6))
    radial = num / den
    d_num = k1 + r2 * (2 * k2 + 3 * k3 * r2)
    d_den = k4 + r2 * (2 * k5 + 3 * k6 * r2)
    dradial = (d_num * den - num * d_den) / den**2  # d radial / d r2
    prism_x = s1 + 2 * s2 * r2  # d (s1 r2 + s2 r2²) / d r2
    prism_y = s3 + 2 * s4 * r2
    jac = np.empty((len(xy), 2, 2))
    jac[:, 0, 0] = radial + 2 * x * x * dradial + 2 * p1 * y + 6 * p2 * x + 2 * x * prism_x
    jac[:, 0, 1] = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y + 2 * y * prism_x
    jac[:, 1, 0] = 2 * x * y * dradial + 2 * p1 * x + 2 * p2 * y + 2 * x * prism_y
    jac[:, 1, 1] = radial + 2 * y * y * dradial + 6 * p1 * y + 2 * p2 * x + 2 * y * prism_y
    return jac


def undistort_px(cv: OpenCvCamera, uv_raw: ArrayLike) -> NDArray[np.float64]:
    """OpenCV's ideal (undistorted) pixels ``K x`` of raw pixels: its distortion inverted
    by Newton's method to 1e-12 (OpenCV's own ``undistortPoints`` stops after 5 fixed-point
    steps by default, too coarse for a round trip)."""
    K = cv.matrix
    uv = np.asarray(uv_raw, dtype=float).reshape(-1, 2)
    target = (uv - K[:2, 2]) / np.diag(K)[:2]
    xy = target.copy()
    for _ in range(100):
        step = np.linalg.solve(
            _distort_jacobian(xy, cv.distortions),
            (_distort(xy, cv.distortions) - target)[..., None],
        )[..., 0]
        xy -= step
        if np.abs(step).max(initial=0.0) < 1e-13:
            break
    return xy * np.diag(K)[:2] + K[:2, 2]


def camera_from_opencv(
    cv: OpenCvCamera, step_px: float = GRID_STEP_PX
) -> tuple[NDArray[np.float64], Linearisation, float]:
    """kisscal's model of an OpenCV camera: the DLT of ``K [R | t]`` and the 4th-order
    linearisation fitted to OpenCV's undistortion over the image.

    Returns
    -------
    L : ndarray, shape (11,)
    linearisation : Linearisation
    rms_px : float
        RMS distance between the polynomial and OpenCV's undistortion over the image.
    """
    w, h = cv.size_px
    raw = image_grid(cv.size_px, step_px)
    ideal = undistort_px(cv, raw)
    centre, scale = ((w - 1) / 2, (h - 1) / 2), (w - 1) / 2
    lin = fit_polynomial(raw, ideal, centre, scale)
    d = np.hypot(*(apply_linearisation(lin, raw) - ideal).T)
    R = cv2.Rodrigues(np.asarray(cv.rotation, dtype=float))[0]
    L = dlt_from_krt(cv.matrix, R, cv.translation_mm)
    return L, lin, float(np.sqrt(np.mean(d**2)))
