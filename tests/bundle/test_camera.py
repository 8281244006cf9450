"""The bundle's camera model: Brown lens and its inverse, DLT exchange, polynomial fit."""

from __future__ import annotations

import numpy as np

from kisscal.bundle.camera import (
    PinholeCamera,
    camera_from_dlt,
    camera_linearisation,
    distort,
    undistort,
    undistort_px,
)
from kisscal.grid import apply_linearisation
from kisscal.synth.cameras import kiss_rig


def test_undistort_inverts_distort_over_the_field() -> None:
    lens = np.array([[-0.25, 0.08, 1e-3, -5e-4, 0.01]])
    xn = np.random.default_rng(0).uniform(-0.6, 0.6, (500, 2))
    back = undistort(lens, distort(lens, xn))
    assert np.abs(back - xn).max() < 1e-12


def test_matches_the_synthetic_cameras_projection() -> None:
    for cam in kiss_rig(4):
        lens = cam.lens
        mine = PinholeCamera(cam.K, cam.R, cam.t, np.array([lens.k1, lens.k2, lens.p1, lens.p2, 0]))
        pts = np.random.default_rng(1).uniform([-1000, -600, 0], [1000, 600, 2000], (50, 3))
        assert np.abs(mine.project(pts) - cam.project(pts)).max() < 1e-9
        assert np.abs(undistort_px(mine, cam.project(pts)) - cam.project_ideal(pts)).max() < 1e-8


def test_dlt_round_trip() -> None:
    cam = kiss_rig(2)[0]
    again = camera_from_dlt(cam.dlt)
    assert np.allclose(again.K, cam.K) and np.allclose(again.R, cam.R, atol=1e-12)
    assert np.allclose(again.centre_mm, cam.centre_mm)


def test_linearisation_polynomial_follows_the_lens_where_the_data_are() -> None:
    """Weighted on the calibration's image positions (the central 80 % here), the 30
    coefficients follow a 6-9 px barrel lens to 0.03 px there; the image corners, with a
    tenth of the weight, stay within 0.35 px."""
    for cam in kiss_rig(5):
        lens = np.array([cam.lens.k1, cam.lens.k2, cam.lens.p1, cam.lens.p2, 0.0])
        w, h = cam.size_px
        data = np.random.default_rng(2).uniform([0.1 * w, 0.1 * h], [0.9 * w, 0.9 * h], (1500, 2))
        pinhole = PinholeCamera(cam.K, cam.R, cam.t, lens)
        lin, fit_max = camera_linearisation(pinhole, cam.size_px, data_px=data)
        err = np.linalg.norm(apply_linearisation(lin, data) - cam.undistort_px(data), axis=1)
        assert err.max() < 0.03 and fit_max < 0.35
