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


def test_linearisation_polynomial_follows_the_lens_to_hundredths() -> None:
    """The 30 coefficients carry a 6-9 px barrel lens to within 0.06 px over the image
    (a 4th-order polynomial cannot follow it exactly; the plain least-squares fit is
    three times worse at the corners)."""
    for cam in kiss_rig(5):
        lens = np.array([cam.lens.k1, cam.lens.k2, cam.lens.p1, cam.lens.p2, 0.0])
        lin, fit_max = camera_linearisation(PinholeCamera(cam.K, cam.R, cam.t, lens), cam.size_px)
        w, h = cam.size_px
        raw = np.random.default_rng(2).uniform([0, 0], [w - 1, h - 1], (400, 2))
        err = np.linalg.norm(apply_linearisation(lin, raw) - cam.undistort_px(raw), axis=1)
        assert fit_max < 0.06 and err.max() < 0.06
