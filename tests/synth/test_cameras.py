"""The synthetic KISS rig: geometry, lens and DLT agree with each other."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt.model import project
from kisscal.synth.cameras import PIXEL_ASPECT, kiss_rig, volume_corners_mm


@pytest.mark.parametrize("seed", [1, 2, 7])
def test_every_camera_sees_the_whole_volume(seed: int) -> None:
    for cam in kiss_rig(seed):
        uv = cam.project(volume_corners_mm())
        assert cam.in_image(uv).all(), cam.id
        assert np.all(cam.depth_mm(volume_corners_mm()) > 1000)


def test_three_cameras_on_each_side_of_the_walkway() -> None:
    y = np.array([c.centre_mm[1] for c in kiss_rig(1)])
    assert (y < -3000).sum() == 3 and (y > 3000).sum() == 3


def test_non_square_pixels_and_principal_point_offsets() -> None:
    rig = kiss_rig(4)
    for cam in rig:
        assert cam.K[1, 1] / cam.K[0, 0] == pytest.approx(PIXEL_ASPECT)
    cx = [cam.K[0, 2] for cam in rig]
    assert np.ptp(cx) > 1.0  # per-camera offsets, not one shared centre


def test_lens_distortion_reaches_several_pixels_at_the_corners() -> None:
    for cam in kiss_rig(2):
        w, h = cam.size_px
        corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], dtype=float)
        shift = np.linalg.norm(cam.undistort_px(corners) - corners, axis=1)
        assert shift.min() >= 5.0, cam.id
        centre = cam.K[:2, 2][None, :]
        assert np.linalg.norm(cam.undistort_px(centre) - centre) < 1e-9


def test_distortion_round_trip() -> None:
    cam = kiss_rig(5)[2]
    rng = np.random.default_rng(0)
    uv = rng.uniform([0, 0], cam.size_px, (1000, 2))
    assert np.abs(cam.distort_px(cam.undistort_px(uv)) - uv).max() < 1e-9


def test_dlt_reproduces_the_ideal_projection() -> None:
    rng = np.random.default_rng(1)
    xyz = rng.uniform([-1200, -700, 0], [1200, 700, 2000], (500, 3))
    for cam in kiss_rig(1):
        assert np.abs(project(cam.dlt, xyz) - cam.project_ideal(xyz)).max() < 1e-8
