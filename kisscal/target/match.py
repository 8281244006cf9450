"""A known target matched automatically from a few clicked points (seeds).

For each camera: a first projection of the target from the seeds (a linear DLT for a
three-dimensional target, Abdel-Aziz & Karara 1971; a plane homography for a flat one),
then rounds of projecting every target point, matching each to the nearest dot found in
the image and fitting again from every match, until the matches stop changing. A match
must be close (within ``gate`` of the distance to the neighbouring target point's
image), unambiguous (the next dot much farther) and mutual (no other target point's
image nearer to that dot), so that a wrong match needs a wrong projection by nearly half
a dot spacing. The last rounds fit a camera with Brown lens terms (OpenCV's
``calibrateCamera``, Zhang 2000 for a flat target) and match once more with it, which
brings in the image corners where a linear model is a few pixels off.

References
----------
Abdel-Aziz, Y. I., & Karara, H. M. (1971). Direct linear transformation from comparator
coordinates into object space coordinates in close-range photogrammetry.
Zhang, Z. (2000). A flexible new technique for camera calibration. IEEE PAMI 22(11).
Brown, D. C. (1971). Close-range camera calibration. Photogramm. Eng. 37(8).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from kisscal.bundle.camera import LENS_TERMS, PinholeCamera, camera_from_dlt
from kisscal.dlt.linear import solve_dlt, spread_ratio
from kisscal.dlt.model import project
from kisscal.dlt.params import DltParams
from kisscal.errors import KisscalError
from kisscal.target.params import DEFAULT_PARAMS, TargetParams

Projector = Callable[[NDArray[np.float64]], NDArray[np.float64]]


@dataclass(frozen=True)
class TargetMatch:
    """One camera's target points matched to its dots.

    Attributes
    ----------
    dot : ndarray of int, shape (n_target,)
        Index of each target point's dot, -1 where unmatched.
    visible : ndarray of bool, shape (n_target,)
        Target points the final camera projects inside the image.
    camera : PinholeCamera
        The camera fitted to every match (lens included).
    rms_px : float
        RMS reprojection residual of the matches (``sqrt(mean(du² + dv²))``).
    seed_rms_px : float
        RMS residual of the seeds under the first model.
    iterations : int
    """

    dot: NDArray[np.int64]
    visible: NDArray[np.bool_]
    camera: PinholeCamera
    rms_px: float
    seed_rms_px: float
    iterations: int

    @property
    def matched(self) -> NDArray[np.bool_]:
        return self.dot >= 0


def is_planar(xyz_mm: ArrayLike) -> bool:
    """True when points lie in one plane (a DLT cannot be fitted to them)."""
    return spread_ratio(xyz_mm) < DltParams().min_spread_ratio


def _plane(xyz: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Origin and rows (in-plane x, in-plane y, normal) of the best plane of points."""
    origin = xyz.mean(axis=0)
    basis = np.linalg.svd(xyz - origin)[2]
    if np.linalg.det(basis) < 0:
        basis[2] = -basis[2]
    return origin, basis


def seed_model(
    seeds_uv: NDArray[np.float64],
    seeds_xyz: NDArray[np.float64],
    target_xyz: NDArray[np.float64],
    camera: str,
    params: TargetParams = DEFAULT_PARAMS,
) -> tuple[Projector, float]:
    """The first projection of the target, from the seeds, and the seeds' RMS residual.

    Raises
    ------
    KisscalError
        Fewer than six seeds, seeds in one plane of a three-dimensional target, or seeds
        that no single camera fits (rms beyond ``seed_tol_px``, the worst seed named).
    """
    where = f"camera {camera}: "
    if len(seeds_uv) < 6:
        raise KisscalError(f"{where}{len(seeds_uv)} seeds; click at least 6 target points")
    if is_planar(seeds_xyz) and not is_planar(target_xyz):
        raise KisscalError(
            f"{where}the seeds lie in one plane; click points on more than one level of the target"
        )
    proj = _fit_projector(seeds_xyz, seeds_uv, is_planar(target_xyz), camera)
    err = np.linalg.norm(proj(seeds_xyz) - seeds_uv, axis=1)
    rms = float(np.sqrt(np.mean(err**2)))
    if rms > params.seed_tol_px:
        worst = int(np.argmax(err))
        raise KisscalError(
            f"{where}the {len(seeds_uv)} seeds contradict each other: no camera puts them "
            f"where they were clicked (rms {rms:.1f} px; seed row {worst + 2} is off by "
            f"{err[worst]:.1f} px); check each click is on the point its x_mm,y_mm,z_mm name"
        )
    return proj, rms


def _fit_projector(
    xyz: NDArray[np.float64], uv: NDArray[np.float64], planar: bool, camera: str
) -> Projector:
    """A linear DLT, or a homography of the plane for a flat target."""
    if not planar:
        L = solve_dlt(xyz, uv, camera=camera)
        return lambda pts: project(L, pts)
    origin, basis = _plane(xyz)
    H, _ = cv2.findHomography((xyz - origin) @ basis[:2].T, uv, 0)
    if H is None:
        raise KisscalError(f"camera {camera}: the target points do not fit a plane's image")

    def homography(pts: NDArray[np.float64]) -> NDArray[np.float64]:
        q = (pts - origin) @ basis[:2].T
        h = q @ H[:, :2].T + H[:, 2]
        return h[:, :2] / h[:, 2:]

    return homography


def match_points(
    projected_px: NDArray[np.float64], dots_px: NDArray[np.float64], params: TargetParams
) -> NDArray[np.int64]:
    """Each projected target point's dot (-1: none close, unambiguous and mutual)."""
    out = np.full(len(projected_px), -1, dtype=np.int64)
    if len(dots_px) < 2 or len(projected_px) < 2:
        return out
    spacing = cKDTree(projected_px).query(projected_px, k=2)[0][:, 1]
    d, j = cKDTree(dots_px).query(projected_px, k=2)
    close = d[:, 0] <= params.gate * spacing
    clear = d[:, 1] >= params.ambiguity * d[:, 0]
    back = cKDTree(projected_px).query(dots_px[j[:, 0]])[1]
    mutual = back == np.arange(len(projected_px))
    ok = close & clear & mutual
    out[ok] = j[ok, 0]
    return out


def fit_camera(
    xyz: NDArray[np.float64],
    uv: NDArray[np.float64],
    size_px: tuple[int, int],
    start: PinholeCamera | None,
    params: TargetParams = DEFAULT_PARAMS,
) -> PinholeCamera:
    """A camera with Brown lens terms fitted to matched points (OpenCV ``calibrateCamera``).

    A flat target is expressed in its own plane (OpenCV's planar calibration, principal
    point held at the image centre since one view of a plane cannot tell it); a
    three-dimensional one starts from ``start`` (the DLT's camera).
    """
    flags = cv2.CALIB_FIX_K3 if "k3" not in params.lens_terms else 0
    for term, flag in (("k1", cv2.CALIB_FIX_K1), ("k2", cv2.CALIB_FIX_K2)):
        if term not in params.lens_terms:
            flags |= flag
    if "p1" not in params.lens_terms and "p2" not in params.lens_terms:
        flags |= cv2.CALIB_ZERO_TANGENT_DIST
    planar = is_planar(xyz)
    origin, basis = _plane(xyz) if planar else (np.zeros(3), np.eye(3))
    obj = (xyz - origin) @ basis.T
    if planar:
        obj[:, 2] = 0.0
        flags |= cv2.CALIB_FIX_PRINCIPAL_POINT
        K0 = np.array([[1.0, 0, (size_px[0] - 1) / 2], [0, 1.0, (size_px[1] - 1) / 2], [0, 0, 1]])
    else:
        flags |= cv2.CALIB_USE_INTRINSIC_GUESS
        assert start is not None
        K0 = start.K.copy()
        K0[0, 1] = 0.0
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    _, K, dist, rvecs, tvecs = cv2.calibrateCamera(
        [obj.astype(np.float32)],
        [uv.astype(np.float32)],
        size_px,
        K0,
        np.zeros(5),
        flags=flags,
        criteria=criteria,
    )
    R_obj = cv2.Rodrigues(rvecs[0])[0]
    R = R_obj @ basis
    t = tvecs[0].ravel() - R @ origin
    return PinholeCamera(K, R, t, np.asarray(dist, dtype=float).ravel()[: len(LENS_TERMS)])


def match_target(
    target_xyz: ArrayLike,
    seeds_uv: ArrayLike,
    seeds_xyz: ArrayLike,
    dots_px: ArrayLike,
    size_px: tuple[int, int],
    camera: str = "",
    params: TargetParams = DEFAULT_PARAMS,
) -> TargetMatch:
    """Match every target point of one camera to its dots, starting from the seeds.

    Parameters
    ----------
    target_xyz : array_like, shape (n, 3)
        Every point of the target (``target.csv``), lab mm.
    seeds_uv, seeds_xyz : array_like, shapes (s, 2), (s, 3)
        The clicked points, s >= 6.
    dots_px : array_like, shape (m, 2)
        The dots found in the camera's images (:mod:`kisscal.target.dots`).
    size_px : (int, int)
        Image width and height.
    camera : str
        Camera id, for messages.
    params : TargetParams

    Raises
    ------
    KisscalError
        Bad seeds (see :func:`seed_model`), or fewer than ``min_matched`` of the visible
        points matched.
    """
    target = np.asarray(target_xyz, dtype=float).reshape(-1, 3)
    dots = np.asarray(dots_px, dtype=float).reshape(-1, 2)
    proj, seed_rms = seed_model(
        np.asarray(seeds_uv, float), np.asarray(seeds_xyz, float), target, camera, params
    )
    planar = is_planar(target)
    dot = np.full(len(target), -1)
    iterations = 0
    while iterations < params.max_iterations:
        iterations += 1
        new = match_points(proj(target), dots, params)
        if np.array_equal(new, dot):
            break
        dot = new
        if (dot >= 0).sum() >= 6:
            proj = _fit_projector(target[dot >= 0], dots[dot[dot >= 0]], planar, camera)
    cam = _lens_rounds(target, dots, dot, size_px, camera, planar, params)
    final = match_points(cam.project(target), dots, params)
    visible = _inside(cam.project(target), size_px)
    m = final >= 0
    if m.sum() < params.min_matched * max(visible.sum(), 1):
        raise KisscalError(
            f"camera {camera}: only {int(m.sum())} of {int(visible.sum())} visible target "
            "points matched a dot; the seeds may name the wrong points, or the dots are not "
            "found (see [target] dots, contrast)"
        )
    cam = fit_camera(target[m], dots[final[m]], size_px, cam, params)
    res = cam.project(target[m]) - dots[final[m]]
    rms = float(np.sqrt(np.mean(np.sum(res**2, axis=1))))
    return TargetMatch(final, visible, cam, rms, seed_rms, iterations)


def _lens_rounds(
    target: NDArray,
    dots: NDArray,
    dot: NDArray,
    size_px: tuple[int, int],
    camera: str,
    planar: bool,
    params: TargetParams,
) -> PinholeCamera:
    m = dot >= 0
    if m.sum() < 12:
        raise KisscalError(
            f"camera {camera}: only {int(m.sum())} target points matched a dot from the seeds; "
            "check the seeds and that the dots are found (see [target] dots, contrast)"
        )
    start = None if planar else camera_from_dlt(solve_dlt(target[m], dots[dot[m]], camera=camera))
    cam = fit_camera(target[m], dots[dot[m]], size_px, start, params)
    for _ in range(2):
        again = match_points(cam.project(target), dots, params)
        k = again >= 0
        cam = fit_camera(target[k], dots[again[k]], size_px, cam, params)
    return cam


def _inside(uv: NDArray[np.float64], size_px: tuple[int, int]) -> NDArray[np.bool_]:
    w, h = size_px
    return (uv[:, 0] >= -0.5) & (uv[:, 0] <= w - 0.5) & (uv[:, 1] >= -0.5) & (uv[:, 1] <= h - 0.5)
