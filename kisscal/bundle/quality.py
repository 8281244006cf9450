"""What a technician reads after a wand calibration, as motion-capture software prints it.

* Wand length over the trial: every field's markers triangulated afresh from the
  calibrated cameras (not taken from the adjusted, rigid wand), their end-to-end
  distance's mean, standard deviation and RMS error against the stated length.
* Per camera: the RMS reprojection residual (px, ``sqrt(mean(du² + dv²))``), the number
  of wand points it contributed and how much of its image the wand covered (the lens
  terms are only as good as that coverage).
* Held out: the wand length error on fields left out of the adjustment, and with rods
  each rod reconstructed by the cameras adjusted without it (leave-one-rod-out, the
  rods route's figure).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.bundle.adjust import WandObservations, adjust_bundle
from kisscal.bundle.params import DEFAULT_PARAMS, BundleParams
from kisscal.bundle.resect import final_cameras
from kisscal.bundle.wand import WandCalibration, select_fields
from kisscal.camera import Camera
from kisscal.dlt.triangulate import triangulate_observations


@dataclass(frozen=True)
class CameraFigures:
    """Per camera: RMS residual (px), wand points used, image cells the wand reached."""

    rms_px: NDArray[np.float64]
    points: NDArray[np.int64]
    coverage: NDArray[np.float64]


def triangulate_points(
    cameras: Sequence[Camera],
    camera: NDArray[np.int64],
    point: NDArray[np.int64],
    uv_px: NDArray[np.float64],
    n_points: int,
) -> NDArray[np.float64]:
    """Least-squares 3D points from observations through the cameras' lenses, (n, 3)."""
    ideal = np.empty_like(uv_px, dtype=float)
    for c, cam in enumerate(cameras):
        rows = camera == c
        if rows.any():
            ideal[rows] = cam.undistort_px(uv_px[rows])
    dlts = np.stack([c.dlt for c in cameras])
    return triangulate_observations(dlts, point, camera, ideal, n_points).xyz_mm


def wand_markers(
    cameras: Sequence[Camera], obs: WandObservations, n_fields: int, n_markers: int
) -> NDArray[np.float64]:
    """Every field's wand markers triangulated from ``obs``, shape (fields, k, 3)."""
    point = obs.field * n_markers + obs.marker
    xyz = triangulate_points(cameras, obs.camera, point, obs.uv_px, n_fields * n_markers)
    return xyz.reshape(n_fields, n_markers, 3)


def end_to_end_mm(markers_xyz: NDArray[np.float64], markers_mm: Sequence[float]) -> NDArray:
    """Distance between the wand's end markers in each field (NaN where one is missing)."""
    s = np.asarray(markers_mm, dtype=float)
    a, b = int(np.argmin(s)), int(np.argmax(s))
    return np.linalg.norm(markers_xyz[:, b] - markers_xyz[:, a], axis=1)


def length_figures(lengths_mm: NDArray[np.float64], nominal_mm: float) -> dict[str, float]:
    """Mean, SD and RMS error (mm) of measured wand lengths, and how many fields."""
    ok = np.isfinite(lengths_mm)
    if not ok.any():
        return {"length_fields": 0}
    d = lengths_mm[ok]
    return {
        "length_mean_mm": float(np.mean(d)),
        "length_sd_mm": float(np.std(d, ddof=1)) if len(d) > 1 else 0.0,
        "length_rms_error_mm": float(np.sqrt(np.mean((d - nominal_mm) ** 2))),
        "length_fields": len(d),
    }


def coverage(uv_px: NDArray[np.float64], size_px: tuple[int, int], cells: int = 8) -> float:
    """Fraction of an image's ``cells`` x ``cells`` tiles holding at least one point."""
    w, h = size_px
    if not len(uv_px):
        return 0.0
    i = np.clip((uv_px[:, 0] + 0.5) / w * cells, 0, cells - 1).astype(int)
    j = np.clip((uv_px[:, 1] + 0.5) / h * cells, 0, cells - 1).astype(int)
    return len(np.unique(i * cells + j)) / cells**2


def camera_figures(cal: WandCalibration, sizes_px: Sequence[tuple[int, int]]) -> CameraFigures:
    """Per-camera residual, points and image coverage of the final adjustment's inliers."""
    r, obs = cal.result, cal.observations
    n = len(cal.cameras)
    rms, points, cover = np.zeros(n), np.zeros(n, np.int64), np.zeros(n)
    for c in range(n):
        rows = (obs.camera == c) & r.inlier
        points[c] = int(rows.sum())
        rms[c] = float(np.sqrt(np.mean(np.sum(r.residuals_px[rows] ** 2, axis=1))))
        cover[c] = coverage(obs.uv_px[rows], sizes_px[c])
    return CameraFigures(rms, points, cover)


def held_out_fields(n_fields: int, params: BundleParams = DEFAULT_PARAMS) -> NDArray[np.bool_]:
    """The wand fields left out for the held-out length: every ``1 / holdout_fraction``-th
    (none with ``holdout_fraction`` 0 or fewer than 10 fields)."""
    if params.holdout_fraction <= 0 or n_fields < 10:
        return np.zeros(n_fields, dtype=bool)
    step = max(2, round(1.0 / params.holdout_fraction))
    return np.arange(n_fields) % step == step // 2


def field_lengths(
    cameras: Sequence[Camera],
    cal: WandCalibration,
    fields: NDArray[np.bool_],
    markers_mm: Sequence[float],
) -> NDArray[np.float64]:
    """Wand lengths (mm) of the marked fields of ``cal``'s inlier observations, measured
    by ``cameras`` (acting on the same coordinates): how another calibration, one that
    never saw these fields, measures the wand."""
    obs = cal.observations.subset(cal.result.inlier)
    test, _, _ = select_fields(obs, cal.result.wand, cal.fields, fields)
    xyz = wand_markers(cameras, test, int(fields.sum()), len(markers_mm))
    return end_to_end_mm(xyz, markers_mm)


def held_out_lengths(
    cal: WandCalibration, markers_mm: Sequence[float], params: BundleParams = DEFAULT_PARAMS
) -> NDArray[np.float64]:
    """Wand lengths (mm) of the :func:`held_out_fields`, measured by cameras adjusted
    without those fields (started from the final adjustment)."""
    held = held_out_fields(len(cal.fields), params)
    if not held.any():
        return np.zeros(0)
    params = cal.refit_params(params)
    obs = cal.observations.subset(cal.result.inlier)
    train, wand, _ = select_fields(obs, cal.result.wand, cal.fields, ~held)
    refit = adjust_bundle(cal.cameras, train, markers_mm, wand, cal.control, params, cal.anchor)
    cameras = final_cameras(refit, train, cal.control, markers_mm, params, cal.dlt)
    return field_lengths(cameras, cal, held, markers_mm)


def paired_length_gain(
    wand_mm: NDArray[np.float64], other_mm: NDArray[np.float64], nominal_mm: float
) -> dict[str, float]:
    """How much lower the wand's squared length errors are than another calibration's on
    the same fields: their mean difference (mm², negative when the wand's are lower),
    its standard error and the fields measured by both (a paired comparison: the
    fields' own noise, common to both, cancels)."""
    ok = np.isfinite(wand_mm) & np.isfinite(other_mm)
    d = (wand_mm[ok] - nominal_mm) ** 2 - (other_mm[ok] - nominal_mm) ** 2
    if len(d) < 2:
        return {"fields": len(d)}
    return {
        "mean_difference_mm2": float(np.mean(d)),
        "standard_error_mm2": float(np.std(d, ddof=1) / np.sqrt(len(d))),
        "fields": len(d),
    }


def leave_one_group_out(
    cal: WandCalibration, markers_mm: Sequence[float], params: BundleParams = DEFAULT_PARAMS
) -> dict[int, NDArray[np.float64]]:
    """3D error (mm) of each control group's points (a rod's markers) when the cameras are
    adjusted without that group, per group."""
    control = cal.control
    if control is None or not len(control):
        return {}
    _, fold, err = leave_control_out(cal, markers_mm, control.group, params)
    return {int(g): err[fold == g] for g in np.unique(fold)}


def leave_control_out(
    cal: WandCalibration,
    markers_mm: Sequence[float],
    fold: NDArray[np.int64],
    params: BundleParams = DEFAULT_PARAMS,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]]:
    """3D error (mm) of the control points of each fold when the cameras are adjusted
    without that fold's observations (started from the final adjustment).

    Parameters
    ----------
    cal : WandCalibration
        With control points.
    markers_mm : sequence of float
    fold : ndarray of int, shape (len(cal.control),)
        The fold of each control observation (all observations of one point in one
        fold; -1: never left out).
    params : BundleParams

    Returns
    -------
    xyz_mm : ndarray, shape (n, 3)
        The left-out points' known positions, fold by fold.
    point_fold : ndarray of int, shape (n,)
    errors_mm : ndarray, shape (n,)
        NaN where fewer than two cameras saw the point.
    """
    control = cal.control
    fold = np.asarray(fold)
    params = cal.refit_params(params)
    obs = cal.observations.subset(cal.result.inlier)
    xyz_out, fold_out, err_out = [np.zeros((0, 3))], [np.zeros(0, np.int64)], [np.zeros(0)]
    for k in np.unique(fold[fold >= 0]):
        rest = control.subset(fold != k)
        refit = adjust_bundle(cal.cameras, obs, markers_mm, cal.result.wand, rest, params)
        cameras = final_cameras(refit, obs, rest, markers_mm, params, cal.dlt)
        mine = control.subset(fold == k)
        ids, point = np.unique(mine.xyz_mm, axis=0, return_inverse=True)
        xyz = triangulate_points(cameras, mine.camera, point.ravel(), mine.uv_px, len(ids))
        xyz_out.append(ids)
        fold_out.append(np.full(len(ids), k, dtype=np.int64))
        err_out.append(np.linalg.norm(xyz - ids, axis=1))
    return np.concatenate(xyz_out), np.concatenate(fold_out), np.concatenate(err_out)
