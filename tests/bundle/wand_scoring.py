"""Scoring calibrations against the true cameras of a synthetic rig (acceptance tables).

* :func:`volume_points`: held-out lab points, never used by any calibration: the inside of
  the volume (the central 60 % of each side) and its shell (beyond 80 %: corners and
  edges, where rods extrapolate).
* :func:`rmse_mm`: those points' images through the true cameras, triangulated through
  the calibrated ones.
* :func:`corner_error_px`: the calibrated lens correction against the true one at the
  image corners, after the best homography between them (a DLT absorbs any homography,
  so only the non-projective part of the correction matters).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from kisscal.bundle.frame import similarity
from kisscal.camera import Camera
from kisscal.dlt.triangulate import triangulate_observations

Undistort = Callable[[NDArray[np.float64]], NDArray[np.float64]]


def volume_points(
    volume_mm: tuple[tuple[float, float, float], tuple[float, float, float]],
    n: int = 4000,
    seed: int = 0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(inside, shell)``: random lab points in the central 60 % and beyond 80 %."""
    lo, hi = np.asarray(volume_mm[0]), np.asarray(volume_mm[1])
    rng = np.random.default_rng(seed)
    unit = rng.uniform(-1.0, 1.0, (n, 3))
    reach = np.abs(unit).max(axis=1)
    pts = (lo + hi) / 2 + unit * (hi - lo) / 2
    return pts[reach <= 0.6][:1000], pts[reach >= 0.8][:1000]


def rmse_mm(
    truth: Sequence[Camera],
    ideal: Sequence[Undistort],
    dlts: NDArray[np.float64],
    xyz_mm: NDArray[np.float64],
    raw: bool,
    shape_only: bool = False,
) -> float:
    """RMS 3D error of points seen by every camera: true images (raw or ideal pixels),
    each calibrated camera's correction ``ideal[c]``, triangulation with ``dlts``.

    ``shape_only``: after the best similarity between the reconstructed and true points,
    i.e. without the error of the lab frame's definition (origin, axes, scale)."""
    cams, pts, uvs = [], [], []
    for c, cam in enumerate(truth):
        uv = cam.project(xyz_mm) if raw else cam.project_ideal(xyz_mm)
        seen = cam.in_image(uv, 2.0) & (cam.depth_mm(xyz_mm) > 0)
        cams.append(np.full(int(seen.sum()), c))
        pts.append(np.flatnonzero(seen))
        uvs.append(ideal[c](uv[seen]))
    tri = triangulate_observations(
        dlts, np.concatenate(pts), np.concatenate(cams), np.concatenate(uvs), len(xyz_mm)
    )
    est = tri.xyz_mm
    if shape_only:
        ok = np.isfinite(est).all(axis=1)
        R, _, scale = similarity(est[ok], xyz_mm[ok])
        moved = est @ R.T
        est = scale * (moved - moved[ok].mean(axis=0)) + xyz_mm[ok].mean(axis=0)
    err = np.linalg.norm(est - xyz_mm, axis=1)
    return float(np.sqrt(np.nanmean(err**2)))


def centre_errors_mm(
    estimated: NDArray[np.float64], truth: Sequence[Camera], rigid: bool = False
) -> NDArray[np.float64]:
    """Distance of each estimated projection centre from the true one (optionally after the
    best rigid motion, for calibrations in an arbitrary frame)."""
    true = np.array([c.centre_mm for c in truth])
    est = np.asarray(estimated, dtype=float)
    if rigid:
        R, _, _ = similarity(est, true)
        est = est @ R.T + true.mean(axis=0) - (est @ R.T).mean(axis=0)
    return np.linalg.norm(est - true, axis=1)


def corner_error_px(truth: Camera, correction: Undistort, samples: int = 31) -> float:
    """Largest error (px) of a lens correction at the four image corners, after the best
    homography between it and the true correction over the image."""
    w, h = truth.size_px
    u, v = np.meshgrid(np.linspace(0, w - 1, samples), np.linspace(0, h - 1, samples))
    raw = np.column_stack([u.ravel(), v.ravel()])
    true = truth.undistort_px(raw)
    got = correction(raw)
    H = _homography(true, got)
    corners = np.array([[0.0, 0.0], [w - 1, 0.0], [0.0, h - 1], [w - 1, h - 1]])
    mapped = _apply(H, truth.undistort_px(corners))
    return float(np.linalg.norm(mapped - correction(corners), axis=1).max())


def _homography(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Least-squares homography ``a -> b`` (DLT on normalised points, then Gauss-Newton)."""
    import cv2
    import scipy.optimize

    H0, _ = cv2.findHomography(a, b, 0)

    def residual(p: NDArray[np.float64]) -> NDArray[np.float64]:
        return (_apply(np.append(p, 1.0).reshape(3, 3), a) - b).ravel()

    p = scipy.optimize.least_squares(residual, (H0 / H0[2, 2]).ravel()[:8], method="lm").x
    return np.append(p, 1.0).reshape(3, 3)


def _apply(H: NDArray[np.float64], pts: NDArray[np.float64]) -> NDArray[np.float64]:
    h = pts @ H[:, :2].T + H[:, 2]
    return h[:, :2] / h[:, 2:]
