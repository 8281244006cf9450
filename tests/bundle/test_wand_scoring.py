"""The scores of the wand acceptance tables (``tests/bundle/wand_acceptance*.py``) measure
what they say: zero for the true cameras, the size of a known error otherwise."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.synth.cameras import VOLUME_MM, kiss_rig
from tests.bundle.wand_scoring import centre_errors_mm, corner_error_px, rmse_mm, volume_points


@pytest.fixture(scope="module")
def rig():
    return kiss_rig(1)


def test_volume_points_are_inside_and_on_the_shell_as_named() -> None:
    inside, shell = volume_points(VOLUME_MM, n=3000, seed=2)
    lo, hi = np.asarray(VOLUME_MM[0]), np.asarray(VOLUME_MM[1])
    reach = lambda p: np.abs((p - (lo + hi) / 2) / ((hi - lo) / 2)).max(axis=1)  # noqa: E731
    assert len(inside) > 100 and len(shell) > 100
    assert reach(inside).max() <= 0.6 and reach(shell).min() >= 0.8


def test_rmse_is_zero_through_the_true_cameras_and_grows_with_a_moved_camera(rig) -> None:
    inside, _ = volume_points(VOLUME_MM, n=2000, seed=3)
    undistort = [cam.undistort_px for cam in rig]
    dlts = np.stack([cam.dlt for cam in rig])
    assert rmse_mm(rig, undistort, dlts, inside, raw=True) < 1e-3
    moved = dlts.copy()
    moved[0, 3] += 5.0  # camera 0's image shifted by about 5 px (L4: u offset)
    worse = rmse_mm(rig, undistort, moved, inside, raw=True)
    assert worse > 0.1
    assert rmse_mm(rig, undistort, moved, inside, raw=True, shape_only=True) < worse


def test_centre_errors_are_distances_and_rigid_removes_a_rigid_motion(rig) -> None:
    true = np.array([c.centre_mm for c in rig])
    off = true + [3.0, 4.0, 0.0]
    assert np.allclose(centre_errors_mm(off, rig), 5.0)
    angle = np.radians(20.0)
    R = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    moved = true @ R.T + [100.0, -50.0, 20.0]
    assert centre_errors_mm(moved, rig, rigid=True).max() < 1e-6
    assert centre_errors_mm(moved, rig).min() > 10.0


def test_corner_error_is_zero_for_the_true_correction_and_not_for_none(rig) -> None:
    cam = rig[0]
    assert corner_error_px(cam, cam.undistort_px) < 1e-3
    uncorrected = corner_error_px(cam, lambda uv: np.asarray(uv, dtype=float))
    w, h = cam.size_px
    corner = np.array([[0.0, 0.0], [w - 1, h - 1]])
    assert uncorrected > 0.05 * np.abs(cam.undistort_px(corner) - corner).max()
