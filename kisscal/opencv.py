"""A calibrated camera in OpenCV's model and back: what anipose, Pose2Sim and OpenCV read.

OpenCV's camera (Bradski 2000; Brown 1966 distortion) is a :class:`kisscal.camera.Camera`
with zero skew, no grid polynomial and Brown's lens (up to OpenCV's 12 coefficients).
A camera kisscal calibrated is the 11-parameter DLT (any skew, Abdel-Aziz & Karara 1971)
on pixel coordinates linearised by a 30-coefficient polynomial (Küçük 2005).
The two models differ: :func:`opencv_from_camera` fits OpenCV's to kisscal's so that their
projections of the same lab points land as close as they can (within the calibrated
volume when it is known, else over the image), and reports what is left;
:func:`camera_from_opencv` goes the other way (the DLT of ``K [R | t]``, a polynomial and
Kolahi's L12..L16 fitted together to OpenCV's undistortion).

Both models project through the same centre (``translation = -R C``), so the fit is one
of directions: the rays through a grid of raw pixels covering the image.

References
----------
Abdel-Aziz, Y. I., & Karara, H. M. (1971). Direct linear transformation from comparator
coordinates into object space coordinates in close-range photogrammetry.
Bradski, G. (2000). The OpenCV library. Dr. Dobb's Journal of Software Tools.
Brown, D. C. (1966). Decentering distortion of lenses. Photogrammetric Engineering.
Kolahi, A., et al. (2007). Design of a marker-based human motion tracking system.
Biomedical Signal Processing and Control 2, 59-67.
Küçük, M. (2005). Calibration and 3D reconstruction for the KISS gait laboratory (thesis).

Examples
--------
>>> import numpy as np
>>> from kisscal.dlt.model import dlt_from_krt
>>> from kisscal.camera import Camera
>>> K = np.array([[800.0, 0, 319.5], [0, 780, 239.5], [0, 0, 1]])
>>> cam = Camera.from_dlt(dlt_from_krt(K, np.eye(3), [0, 0, 3000.0]), "c1", size_px=(640, 480))
>>> fit = opencv_from_camera(cam)
>>> bool(fit.rms_px < 1e-6), np.round(fit.camera.K[0, 0], 3)
(True, np.float64(800.0))
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.spatial import ConvexHull, QhullError

from kisscal._shared import as_points, rms_px
from kisscal.camera import Camera, distort, distort_each
from kisscal.dlt.camera import decompose_dlt
from kisscal.dlt.model import dlt_to_matrix
from kisscal.dlt.nonlinear import N_LENS, correct_lens, lens_frame, lens_offsets
from kisscal.errors import InputError
from kisscal.grid.poly import Linearisation, apply_linearisation, fit_polynomial, poly_terms

#: Raw pixels per side of the grid over which the models are fitted and compared.
GRID_STEP_PX = 12.0
#: Lattice points per side of the calibrated volume the fit follows (:func:`volume_rays`).
VOLUME_SAMPLES = 20
#: Cap on the evaluations of the joint fit of the polynomial and L12..L16 on import.
MAX_NFEV = 40
#: Cap on the evaluations of the export's fit (Levenberg-Marquardt, 19 parameters): on a
#: flat valley of the 12 coefficients it creeps on for thousands without a visible gain.
EXPORT_MAX_NFEV = 400
#: Weight, on import, of the image beyond the region the export fitted (``region_px``).
REGION_OUTSIDE_WEIGHT = 1e-3


@dataclass(frozen=True)
class OpenCvFit:
    """An OpenCV camera fitted to a kisscal camera, and how close it lands.

    Attributes
    ----------
    camera : Camera
        Zero skew, Brown's lens of 5, 8 or 12 coefficients, no polynomial.
    rms_px, max_px : float
        RMS (``sqrt(mean(du² + dv²))``) and largest distance between the two models'
        projections over a grid of raw pixels covering the image.
    skew_px : float
        The DLT's skew ``K[0, 1]`` (px), which OpenCV's matrix cannot hold.
    region_px : tuple of 4 float or None
        ``(u_min, v_min, u_max, v_max)``, raw px: where the fit follows kisscal's camera
        (the calibrated volume's or the control points' extent in the image); None when
        it follows the whole image. Beyond it OpenCV's model extrapolates.
    """

    camera: Camera
    rms_px: float
    max_px: float
    skew_px: float
    region_px: tuple[float, float, float, float] | None = None


def image_grid(size_px: tuple[int, int], step_px: float = GRID_STEP_PX) -> NDArray[np.float64]:
    """Raw pixel positions covering the whole image, corners included, shape (n, 2)."""
    w, h = size_px
    u = np.linspace(-0.5, w - 0.5, max(round(w / step_px), 2) + 1)
    v = np.linspace(-0.5, h - 0.5, max(round(h / step_px), 2) + 1)
    return np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)


def _project(theta: NDArray[np.float64], rays: NDArray[np.float64]) -> NDArray[np.float64]:
    """Pixels of camera-centred lab directions under parameters ``theta``:
    Rodrigues (3), fx, fy, cx, cy, then the distortion vector (5, 8 or 12)."""
    xy = distort(theta[7:], _normalised(theta, rays))
    return xy * theta[3:5] + theta[5:7]


def _normalised(theta: NDArray[np.float64], rays: NDArray[np.float64]) -> NDArray[np.float64]:
    """Undistorted normalised coordinates of camera-centred lab directions under the
    rotation ``theta[0:3]`` (Rodrigues)."""
    R = cv2.Rodrigues(theta[0:3])[0]
    pc = rays @ R.T
    return pc[:, :2] / pc[:, 2:3]


class _ExportResiduals:
    """The export fit's weighted pixel residuals (:func:`opencv_from_camera`) as a
    function of its free parameters ``x`` (``theta[free]``), and their Jacobian.

    The Jacobian is the forward difference scipy's ``least_squares`` takes by default
    (``jac="2-point"``: step ``sqrt(eps) max(1, |x|)``, its sign ``x``'s), value for
    value, but each column recomputes only what its parameter moves: the rays' rotation
    for the three rotation parameters, the terms of Brown's distortion a lens coefficient
    enters (:func:`kisscal.camera.distort_each`), the last scaling for the four of the
    matrix. The residuals are computed on flat arrays (u, v interleaved, as the fit
    reads them), the same operations on the same numbers as :func:`_project`. The fit
    walks the same path to the same numbers in about two thirds of the time.
    """

    def __init__(
        self,
        theta0: NDArray[np.float64],
        free: NDArray[np.bool_],
        rays: NDArray[np.float64],
        raw: NDArray[np.float64],
        weight: NDArray[np.float64],
    ) -> None:
        self.theta0, self.free, self.rays = theta0, free, rays
        self.raw = raw.ravel()  # u0 v0 u1 v1 ...
        self.weight = np.repeat(weight.ravel(), 2)

    def theta(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Every parameter, the free ones from ``x``."""
        th = self.theta0.copy()
        th[self.free] = x
        return th

    def __call__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        th = self.theta(x)
        return self._weighted(distort(th[7:], _normalised(th, self.rays)), th)

    def _weighted(self, xy: NDArray[np.float64], th: NDArray[np.float64]) -> NDArray[np.float64]:
        """Weighted residuals of distorted normalised coordinates (n, 2) under the
        matrix of ``th``: ``(xy * (fx, fy) + (cx, cy) - raw) * weight``, flat."""
        n = len(xy)
        return (xy.ravel() * np.tile(th[3:5], n) + np.tile(th[5:7], n) - self.raw) * self.weight

    def jacobian(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """d residuals / d x by forward differences, shape (residuals, free)."""
        th = self.theta(x)
        xn = _normalised(th, self.rays)
        xy = distort(th[7:], xn)
        f0 = self._weighted(xy, th)
        sign = (x >= 0).astype(float) * 2 - 1
        step = np.finfo(np.float64).eps ** 0.5 * sign * np.maximum(1.0, np.abs(x))
        index = np.flatnonzero(self.free)
        moved = th.copy()
        moved[index] = x + step
        lens = distort_each(th[7:], xn, moved[7:])
        jac_t = np.empty((x.size, f0.size))
        for i, p in enumerate(index):
            one = th.copy()
            one[p] = moved[p]
            if p < 3:  # the rotation: the rays turn
                moved_xy = distort(one[7:], _normalised(one, self.rays))
            else:  # the matrix: the last scaling; a lens coefficient: its terms
                moved_xy = xy if p < 7 else lens[p - 7]
            jac_t[i] = (self._weighted(moved_xy, one) - f0) / ((x[i] + step[i]) - x[i])
        return jac_t.T


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


def fit_weights(
    raw: NDArray[np.float64],
    size_px: tuple[int, int],
    used_px: NDArray[np.float64] | None,
    rim: tuple[float, float],
    outside_weight: float,
) -> NDArray[np.float64]:
    """Weight of each fit position: 1 within the bounding box of ``used_px`` (the raw
    pixels of the points the calibration used) and ``outside_weight`` beyond it; without
    them (or fewer than 3), :func:`rim_weights` with ``rim`` = (fraction, weight)."""
    if used_px is None or len(used_px) < 3:
        return rim_weights(raw, size_px, *rim)
    lo, hi = np.min(used_px, axis=0), np.max(used_px, axis=0)
    inside = np.all((raw >= lo) & (raw <= hi), axis=1)
    return np.where(inside, 1.0, outside_weight)


def volume_rays(
    camera: Camera,
    volume_mm: tuple[ArrayLike, ArrayLike],
    samples: int = VOLUME_SAMPLES,
    hull_mm: ArrayLike | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Raw pixels and lab directions (from the camera's centre) of a ``samples``-per-side
    lattice of lab points filling ``volume_mm`` (lowest, highest corner), those the
    camera images in front of it and on its image; with ``hull_mm`` (lab points, mm),
    only those within the points' convex hull (:func:`within_hull`)."""
    lo, hi = (np.asarray(c, dtype=float) for c in volume_mm)
    axes = [np.linspace(a, b, samples) for a, b in zip(lo, hi, strict=True)]
    xyz = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    if hull_mm is not None:
        xyz = xyz[within_hull(xyz, hull_mm)]
    xyz = xyz[camera.depth_mm(xyz) > 0]
    # the volume of all cameras reaches far outside this one's view, where the inverse
    # of its linearisation and lens terms does not converge: only points its linearised
    # image shows go on
    xyz = xyz[camera.in_image(camera.project_ideal(xyz))]
    raw = camera.project(xyz)
    seen = camera.in_image(raw) & np.isfinite(raw).all(axis=1)
    return raw[seen], xyz[seen] - camera.centre_mm


def within_hull(xyz: NDArray[np.float64], points_mm: ArrayLike) -> NDArray[np.bool_]:
    """Whether each lab point lies within the convex hull of ``points_mm`` (Quickhull,
    Barber, Dobkin & Huhdanpaa 1996), its faces included to a millionth of the hull's
    size; all True when the points span no volume (fewer than 4, or flat)."""
    pts = as_points(points_mm, 3, "points_mm")
    try:
        faces = ConvexHull(pts).equations  # unit normal n and offset d: n.x + d <= 0 inside
    except (QhullError, ValueError):
        return np.ones(len(xyz), dtype=bool)
    tol = 1e-6 * float(np.linalg.norm(np.ptp(pts, axis=0)))
    return np.all(xyz @ faces[:, :3].T + faces[:, 3] <= tol, axis=1)


def opencv_from_camera(
    camera: Camera,
    coefficients: int = 12,
    *,
    k3: bool = True,
    used_px: NDArray[np.float64] | None = None,
    volume_mm: tuple[ArrayLike, ArrayLike] | None = None,
    hull_mm: ArrayLike | None = None,
) -> OpenCvFit:
    """OpenCV's model fitted to a kisscal camera: matrix, distortions and rotation by
    least squares (Levenberg-Marquardt) on the rays through a grid of raw pixels covering
    the image; the centre is the DLT's (Woltring & Huiskes 1990, eq. 15).

    ``coefficients`` is the length of the distortion vector: 5 (``k1 k2 p1 p2 k3``),
    8 (with the rational model's ``k4 k5 k6``) or 12 (and the thin prism's ``s1..s4``).
    OpenCV's functions, and so anipose and Pose2Sim, accept all three; 12 follows a
    grid's 4th-order polynomial best (a third to a half of the 5-term model's 3D error
    on the synthetic rigs). The image's rim (8 % of its smaller side) counts a tenth
    as much as its inside: there the polynomial extrapolates
    beyond the grid's dots, and no model follows it there without giving up the inside,
    where the measurements are.

    ``k3`` False holds the third radial term at 0 (with ``coefficients=5``): the four
    coefficients ``k1 k2 p1 p2`` that Pose2Sim writes and reads.

    ``used_px``, the raw pixels of the points the calibration used (its control points),
    replaces the rim rule: the fit follows kisscal's camera within their bounding box and
    counts 1 % as much beyond it, where no measurement backs either model
    (on the synthetic kiss and webcam rigs this lowered the round trip through
    ``cameras.toml`` by a fifth to a third).

    ``volume_mm``, the calibrated volume (lowest and highest corner, lab mm: the extent
    of the control points), replaces both: the fit follows kisscal's camera on the rays
    to a lattice of points filling it (:func:`volume_rays`), as densely as the volume
    fills the image, and on the grid of raw pixels at 0.001 each. A lab
    measures within its volume, so that is where the two models must agree: on the
    synthetic webcam rigs this halved the 3D gap between them against the control
    points' extent in the image. Each volume point's pixel residual is weighted by its
    depth squared (the lateral mm it moves the ray there); with 20 points per side
    instead of 12 this took a sixth off the 3D gap on the synthetic webcam rigs. What
    the fit cannot follow is mostly the DLT's skew, which OpenCV's matrix cannot hold
    (``skew_px``): without it the gap halves there.

    ``hull_mm``, the control points themselves (lab mm), keeps of that lattice only the
    points within their convex hull: a wand waved through a room fills its bounding
    box's middle, not its corners, and the fit spent itself there on a volume no point
    calibrated and no lab measures in (on the synthetic rigs' wand calibrations this
    took a tenth to a third off the ``cameras.toml`` round trip, webcams 0.0166, 0.0134,
    0.0137 -> 0.0135, 0.0114, 0.0112 mm; the rods', whose hull is nearly their box,
    moved by 0.0005 mm or less).

    Raises
    ------
    KisscalError
        When the camera's image size is unknown, or ``coefficients`` is not 5, 8 or 12.
    """
    if camera.size_px is None:
        raise InputError(f"camera {camera.id}: image size unknown; cannot fit OpenCV's model")
    if coefficients not in (5, 8, 12):
        raise InputError(f"OpenCV distortion coefficients must be 5, 8 or 12, got {coefficients}")
    K, R, centre = decompose_dlt(camera.dlt)
    raw = image_grid(camera.size_px)
    weight = fit_weights(raw, camera.size_px, used_px, (0.08, 0.1), 0.01)
    region = _extent(used_px)
    uv = camera.undistort_px(raw)
    rays = np.c_[uv, np.ones(len(uv))] @ np.linalg.inv(K).T @ R  # lab directions, forward
    if volume_mm is not None:
        raw_v, rays_v = volume_rays(camera, volume_mm, hull_mm=hull_mm)
        raw, rays = np.r_[raw, raw_v], np.r_[rays, rays_v]
        weight = np.r_[np.full(len(weight), 1e-3), _lateral_weights(rays_v @ R[2])]
        region = _extent(raw_v)
    weight = np.sqrt(weight)[:, None]
    rvec = cv2.Rodrigues(R)[0].ravel()
    theta0 = np.r_[rvec, K[0, 0], K[1, 1], K[0, 2], K[1, 2], np.zeros(coefficients)]
    free = np.ones(theta0.size, dtype=bool)
    free[11] = k3  # theta[11] is k3 (distortions start at theta[7]: k1 k2 p1 p2 k3 ...)

    residuals = _ExportResiduals(theta0, free, rays, raw, weight)
    th = residuals.theta(
        least_squares(
            residuals,
            theta0[free],
            jac=residuals.jacobian,
            method="lm",
            x_scale="jac",
            max_nfev=EXPORT_MAX_NFEV,
        ).x
    )
    R_fit = cv2.Rodrigues(th[0:3])[0]
    matrix = np.array([[th[3], 0.0, th[5]], [0.0, th[4], th[6]], [0.0, 0.0, 1.0]])
    cv = Camera(matrix, R_fit, -R_fit @ centre, th[7:].copy(), camera.id, camera.size_px)
    d = np.hypot(*(_project(th, rays) - raw).T)
    return OpenCvFit(cv, float(np.sqrt(np.mean(d**2))), float(d.max()), float(K[0, 1]), region)


def _lateral_weights(depth_mm: NDArray[np.float64]) -> NDArray[np.float64]:
    """Weight of each volume point's pixel residual: its depth squared (relative to the
    median), so that the fit weighs the lateral mm a pixel's error displaces the ray by
    at the point, the error a lab measures."""
    if len(depth_mm) == 0:
        return depth_mm
    return (depth_mm / np.median(depth_mm)) ** 2


def _extent(uv: NDArray[np.float64] | None) -> tuple[float, float, float, float] | None:
    """``(u_min, v_min, u_max, v_max)`` of 3 pixels or more, else None."""
    if uv is None or len(uv) < 3:
        return None
    lo, hi = np.min(uv, axis=0), np.max(uv, axis=0)
    return (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))


def camera_from_opencv(
    cv: Camera, lens_terms: bool = True, region_px: ArrayLike | None = None
) -> tuple[Camera, float]:
    """kisscal's model of an OpenCV camera: the DLT of ``K [R | t]``, a 4th-order
    linearisation and, with ``lens_terms``, Kolahi's L12..L16 on top, fitted together to
    OpenCV's undistortion over the image.

    A 4th-order polynomial follows a moderate lens to a few hundredths of a pixel; the
    radial terms of a stronger one (``k2``, ``k3``, the rational model's: 5th order and
    beyond) it cannot. L12..L16 are radial about the principal point in square pixels
    (:func:`kisscal.dlt.nonlinear.lens_offsets`), as OpenCV's are in normalised
    coordinates, up to ``r^6``: started from their least-squares fit alone and the
    polynomial to the rest, both are then adjusted together (Levenberg-Marquardt);
    they are kept when they follow OpenCV's camera closer than the polynomial alone.

    ``region_px`` (``u_min, v_min, u_max, v_max``, raw px), where the OpenCV model was
    fitted to follow a calibration (kisscal's export writes it,
    :func:`kisscal.io.cameras_toml.read_fit_regions`): the fit follows OpenCV's camera
    there and counts :data:`REGION_OUTSIDE_WEIGHT` as much beyond it, where OpenCV's model only
    extrapolates; on the synthetic webcam rigs this cut the import's share of the
    ``cameras.toml`` round trip by two thirds.

    Returns
    -------
    camera : Camera
        The DLT of ``K [R | t]`` (:attr:`Camera.dlt`, as OpenCV's matrix gives it), its
        ``linearisation`` and ``kolahi`` (L12..L16, or None); no Brown terms.
    rms_px : float
        The RMS distance between kisscal's undistortion and OpenCV's over the image
        (within ``region_px`` when given).
    """
    w, h = cv.size_px
    raw = image_grid(cv.size_px)
    ideal = cv.undistort_px(raw)
    weight = region_weights(raw, region_px, REGION_OUTSIDE_WEIGHT)
    inside = weight == 1.0
    root_w = np.sqrt(weight)[:, None]
    centre, scale = ((w - 1) / 2, (h - 1) / 2), (w - 1) / 2
    lin = fit_polynomial(raw, ideal, centre, scale, weights=weight)
    plain_rms = rms_px((apply_linearisation(lin, raw) - ideal)[inside])
    plain = (Camera.from_dlt(cv.dlt, cv.id, lin, None, cv.size_px), plain_rms)
    if not lens_terms or plain_rms < 1e-6:
        return plain
    frame = lens_frame(dlt_to_matrix(cv.dlt))
    basis = np.stack([lens_offsets(raw, frame, e) for e in np.eye(N_LENS)], axis=-1)
    unit = np.abs(basis).reshape(-1, N_LENS).max(axis=0)  # each term's largest shift, px
    x0, *_ = np.linalg.lstsq(
        (basis / unit * root_w[:, :, None]).reshape(-1, N_LENS), ((ideal - raw) * root_w).ravel()
    )
    lin0 = fit_polynomial(raw, _uncorrect(cv.dlt, x0 / unit, ideal), centre, scale, weight)
    n = len(lin0.x)
    terms = poly_terms((raw[:, 0] - centre[0]) / scale, (raw[:, 1] - centre[1]) / scale)

    def split(p: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        return terms @ np.c_[p[:n], p[n : 2 * n]], p[2 * n :] / unit

    def gaps(p: NDArray[np.float64]) -> NDArray[np.float64]:
        uv, lens = split(p)
        return uv + lens_offsets(uv, frame, lens) - ideal

    def jacobian(p: NDArray[np.float64]) -> NDArray[np.float64]:
        uv, lens = split(p)
        step = 1e-3  # px; the terms are polynomials, central differences are exact enough
        d = [
            lens_offsets(uv + e, frame, lens) - lens_offsets(uv - e, frame, lens)
            for e in np.eye(2) * step
        ]
        grad = np.eye(2) + np.stack(d, axis=-1) / (2 * step)  # (n, 2, 2): d(corrected)/d(uv)
        by_lens = np.stack([lens_offsets(uv, frame, e) for e in np.eye(N_LENS)], axis=-1)
        jac = np.concatenate(
            [grad[:, :, :1] * terms[:, None], grad[:, :, 1:] * terms[:, None], by_lens / unit],
            axis=2,
        )
        return (jac * root_w[:, :, None]).reshape(-1, jac.shape[2])

    p0 = np.r_[lin0.x, lin0.y, x0]
    p = least_squares(
        lambda q: (gaps(q) * root_w).ravel(),
        p0,
        jac=jacobian,
        method="lm",
        x_scale="jac",
        max_nfev=MAX_NFEV,
    ).x
    lin_p = Linearisation(centre, scale, p[:n], p[n : 2 * n])
    rms = rms_px(gaps(p)[inside])
    if rms >= plain_rms:
        return plain
    return Camera.from_dlt(cv.dlt, cv.id, lin_p, p[2 * n :] / unit, cv.size_px), rms


def region_weights(
    raw: NDArray[np.float64], region_px: ArrayLike | None, outside_weight: float
) -> NDArray[np.float64]:
    """Weight of each fit position: 1 within ``region_px`` (``u_min, v_min, u_max,
    v_max``) and ``outside_weight`` beyond; all 1 without a region."""
    if region_px is None:
        return np.ones(len(raw))
    box = np.asarray(region_px, dtype=float).ravel()
    if box.shape != (4,) or not np.all(np.isfinite(box)) or np.any(box[2:] <= box[:2]):
        raise InputError(f"fit region must be u_min, v_min, u_max, v_max (px), got {box}")
    inside = np.all((raw >= box[:2]) & (raw <= box[2:]), axis=1)
    return np.where(inside, 1.0, outside_weight)


def _uncorrect(
    L: NDArray[np.float64], lens: NDArray[np.float64], ideal: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The pixels that L12..L16 take to ``ideal`` (fixed point: the terms are smooth)."""
    uv = ideal.copy()
    for _ in range(100):
        step = ideal - correct_lens(L, lens, uv)
        uv += step
        if np.abs(step).max() < 1e-12:
            break
    return uv
