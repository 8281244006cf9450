"""Linear DLT: exact on exact data, rms_px as defined, clear errors on degenerate input."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt import DltParams, calibrate_camera, project, reprojection_residuals, rms_px
from kisscal.dlt.linear import solve_dlt
from kisscal.errors import KisscalError
from tests.dlt.conftest import rod_xyz


def test_exact_data_gives_the_true_parameters(rig):
    xyz = rod_xyz(rig)
    for L_true in rig.L:
        L = solve_dlt(xyz, project(L_true, xyz))
        np.testing.assert_allclose(L, L_true, rtol=1e-7, atol=1e-12)


def test_far_lab_origin_is_conditioned_by_normalisation(rig):
    # Lab coordinates 100 m from the origin: without Hartley normalisation the linear
    # system is ill-conditioned; the reprojection must still be exact.
    shift = np.array([1e5, -2e5, 5e4])
    xyz = rod_xyz(rig) + shift
    rng = np.random.default_rng(3)
    probe = rng.uniform([0, 0, 0], [2400, 1400, 2000], (50, 3)) + shift
    L_true = rig.L[1].copy()
    # Same camera moved with the lab: P' = P T^-1
    P = np.append(L_true, 1).reshape(3, 4)
    T = np.eye(4)
    T[:3, 3] = -shift
    Ps = P @ T
    Ls = (Ps / Ps[2, 3]).ravel()[:11]
    L = solve_dlt(xyz, project(Ls, xyz))
    assert np.abs(project(L, probe) - project(Ls, probe)).max() < 1e-6


def test_rms_px_is_the_rms_euclidean_distance(rig):
    xyz = rod_xyz(rig)
    rng = np.random.default_rng(1)
    uv = project(rig.L[0], xyz) + rng.normal(0, 0.05, (len(xyz), 2))
    result = calibrate_camera(xyz, uv)
    du, dv = (uv - project(result.L, xyz)).T
    assert result.rms_px == pytest.approx(np.sqrt(np.mean(du**2 + dv**2)), rel=1e-12)
    np.testing.assert_allclose(result.residuals_px, reprojection_residuals(result.L, xyz, uv))
    # Not the per-coordinate RMS, which is 1/sqrt(2) of it
    per_coordinate = np.sqrt(np.mean(np.concatenate([du, dv]) ** 2))
    assert rms_px(result.residuals_px) == pytest.approx(np.sqrt(2) * per_coordinate)
    assert 0.02 < result.rms_px < 0.08


def test_fewer_than_six_points_is_refused(rig):
    xyz = rod_xyz(rig)[[0, 5, 6, 12, 18]]
    with pytest.raises(KisscalError, match="at least 6 control points, got 5"):
        solve_dlt(xyz, project(rig.L[0], xyz), camera="cam1")


def test_coplanar_points_are_refused(rig):
    # Two rods span a vertical plane
    xyz = rod_xyz(rig)[:12]
    with pytest.raises(KisscalError, match="camera cam2: the 12 control points are coplanar"):
        calibrate_camera(xyz, project(rig.L[1], xyz), camera="cam2")


def test_nan_and_shape_errors(rig):
    xyz = rod_xyz(rig)
    uv = project(rig.L[0], xyz)
    uv[3, 0] = np.nan
    with pytest.raises(KisscalError, match="NaN"):
        solve_dlt(xyz, uv)
    with pytest.raises(KisscalError, match=r"xyz \(N, 3\) and uv \(N, 2\)"):
        solve_dlt(xyz, uv[:10])


def test_min_points_is_a_parameter(rig):
    xyz = rod_xyz(rig)[::2]
    with pytest.raises(KisscalError, match="at least 20"):
        solve_dlt(xyz, project(rig.L[0], xyz), DltParams(min_points=20))
