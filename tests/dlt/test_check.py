"""n-camera triangulation and the leave-one-rod-out check."""

from __future__ import annotations

import numpy as np

from kisscal.dlt import DltParams, leave_one_rod_out, project, triangulate_dlt
from kisscal.dlt.check import leave_folds_out
from tests.dlt.conftest import kiss_rig, rod_xyz


def test_triangulation_is_exact_on_exact_data(rig):
    rng = np.random.default_rng(0)
    xyz = rng.uniform([0, 0, 0], [2400, 1400, 2000], (40, 3))
    uv = np.stack([project(L, xyz) for L in rig.L])
    uv[0, :5] = np.nan  # not seen by camera 1
    uv[1:, 0] = np.nan  # point 0 seen by no camera at all
    uv[2:, 1] = np.nan  # point 1 seen by camera 1 only... (and camera 0 hides it)
    rec, n_cam = triangulate_dlt(rig.L, uv)
    assert np.isnan(rec[:2]).all() and n_cam[0] == 0 and n_cam[1] == 1
    np.testing.assert_allclose(rec[2:], xyz[2:], atol=1e-6)
    assert n_cam[2] == 5 and n_cam[10] == 6


def test_reweighting_reduces_the_error_of_noisy_points(rig):
    rng = np.random.default_rng(1)
    xyz = rng.uniform([0, 0, 0], [2400, 1400, 2000], (2000, 3))
    uv = np.stack([project(L, xyz) for L in rig.L]) + rng.normal(0, 0.2, (6, 2000, 2))
    plain, _ = triangulate_dlt(rig.L, uv, iterations=0)
    weighted, _ = triangulate_dlt(rig.L, uv, iterations=2)
    e_plain = np.linalg.norm(plain - xyz, axis=1).mean()
    e_weighted = np.linalg.norm(weighted - xyz, axis=1).mean()
    assert e_weighted <= e_plain * 1.001


def _marker_uv(rig, rng, noise_px):
    uv = np.stack([project(L, rod_xyz(rig)) for L in rig.L])
    return (uv + rng.normal(0, noise_px, uv.shape)).reshape(len(rig.L), 4, 6, 2)


def test_leave_one_rod_out_reports_each_rod():
    rig = kiss_rig(2)
    rng = np.random.default_rng(2)
    muv = _marker_uv(rig, rng, 0.05)
    muv[0, 1, 2] = np.nan  # one marker not identified in one camera
    check = leave_one_rod_out(muv, rig.rods, cameras=[f"cam{i}" for i in range(6)])
    assert check.rod_names == ("R1", "R2", "R3", "R4")
    np.testing.assert_array_equal(check.n_markers, [6, 6, 6, 6])
    assert np.all(check.mean_mm > 0) and np.all(check.max_mm >= check.mean_mm)
    # Extrapolating to an edge of the volume is harsher than in-sample, yet mm-level here
    assert check.overall_mean_mm < 5
    exact = leave_one_rod_out(_marker_uv(rig, rng, 0.0), rig.rods)
    assert exact.overall_max_mm < 1e-6
    refined = leave_one_rod_out(muv, rig.rods, DltParams(mdlt=True, refine=True))
    assert np.isfinite(refined.overall_mean_mm)


def test_markers_held_out_between_calibrated_ones_are_not_extrapolated():
    rig = kiss_rig(3)
    rng = np.random.default_rng(3)
    muv = _marker_uv(rig, rng, 0.1)
    fold = np.tile(np.arange(6) % 3, (4, 1))
    fold[2, 5] = -1  # never left out
    errors = leave_folds_out(muv, rig.rods, fold)
    assert errors.shape == (4, 6) and np.isnan(errors[2, 5])
    assert np.isfinite(np.delete(errors.ravel(), 2 * 6 + 5)).all()
    # a rod's index as its fold is leave-one-rod-out, marker for marker
    by_rod = leave_folds_out(muv, rig.rods, np.repeat(np.arange(4), 6).reshape(4, 6))
    np.testing.assert_allclose(by_rod, leave_one_rod_out(muv, rig.rods).errors_mm)
    # held out between calibrated markers: no extrapolation, smaller errors
    assert np.nanmean(errors) < 0.5 * np.nanmean(by_rod)
    exact = leave_folds_out(_marker_uv(rig, rng, 0.0), rig.rods, fold)
    assert np.nanmax(exact) < 1e-6


def test_parallel_rays_give_nan_not_an_exception(rig):
    xyz = rod_xyz(rig)
    uv = np.stack([project(rig.L[0], xyz)] * 3)
    rec, n_cam = triangulate_dlt(np.stack([rig.L[0]] * 3), uv)
    assert np.isnan(rec).all() and np.all(n_cam == 3)
