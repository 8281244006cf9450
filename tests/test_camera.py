"""kisscal's one camera model: Brown lens and its inverse, OpenCV's projection, DLT
exchange, the grid polynomial fitted to a lens."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from kisscal.camera import (
    Camera,
    camera_linearisation,
    distort,
    distortion_jacobian,
    undistort,
)
from kisscal.errors import KisscalError
from kisscal.grid import apply_linearisation
from kisscal.synth.cameras import kiss_rig

#: A wide-angle lens in each of OpenCV's layouts (k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4).
LENSES = [
    np.array([-0.25, 0.08, 1e-3, -5e-4]),
    np.array([-0.25, 0.08, 1e-3, -5e-4, 0.01]),
    np.array([-0.25, 0.08, 1e-3, -5e-4, 0.01, 0.05, -0.01, 0.002]),
    np.array([-0.25, 0.08, 1e-3, -5e-4, 0.01, 0.05, -0.01, 0.002, 1e-3, -2e-4, 5e-4, 1e-4]),
]


@pytest.mark.parametrize("lens", LENSES, ids=lambda d: f"{len(d)} terms")
def test_undistort_inverts_distort_over_the_field(lens) -> None:
    xn = np.random.default_rng(0).uniform(-0.6, 0.6, (500, 2))
    back = undistort(lens, distort(lens, xn))
    assert np.abs(back - xn).max() < 1e-12


@pytest.mark.parametrize("lens", LENSES, ids=lambda d: f"{len(d)} terms")
def test_distortion_jacobian_matches_finite_differences(lens) -> None:
    xn = np.random.default_rng(1).uniform(-0.6, 0.6, (50, 2))
    h = 1e-6
    numeric = np.stack(
        [(distort(lens, xn + h * e) - distort(lens, xn - h * e)) / (2 * h) for e in np.eye(2)],
        axis=-1,
    )
    assert np.abs(distortion_jacobian(lens, xn) - numeric).max() < 1e-8


def test_one_lens_per_row_is_each_rows_own_lens() -> None:
    xn = np.random.default_rng(2).uniform(-0.5, 0.5, (2, 2))
    per_row = distort(np.stack(LENSES[1:2] * 2) * [[1.0], [0.5]], xn)
    assert np.allclose(per_row[0], distort(LENSES[1], xn[:1])[0])
    assert np.allclose(per_row[1], distort(LENSES[1] * 0.5, xn[1:])[0])


@pytest.mark.parametrize("lens", LENSES, ids=lambda d: f"{len(d)} terms")
def test_projection_is_opencvs(lens) -> None:
    """The camera projects lab points where ``cv2.projectPoints`` does, in every layout."""
    K = np.array([[1400.0, 0.0, 650.0], [0, 1390.0, 500.0], [0, 0, 1]])
    rvec = np.array([2.0, 0.3, -0.2])
    cam = Camera(K, cv2.Rodrigues(rvec)[0], np.array([150.0, -300.0, 4200.0]), lens)
    xyz = np.random.default_rng(3).uniform(-800, 800, (200, 3))
    theirs = cv2.projectPoints(xyz[:, None], rvec, cam.t, K, lens)[0].reshape(-1, 2)
    assert np.abs(cam.project(xyz) - theirs).max() < 1e-7


def test_synthetic_cameras_are_opencvs_and_their_dlt() -> None:
    for cam in kiss_rig(4):
        pts = np.random.default_rng(1).uniform([-1000, -600, 0], [1000, 600, 2000], (50, 3))
        rvec = cv2.Rodrigues(cam.R)[0]
        theirs = cv2.projectPoints(pts[:, None], rvec, cam.t, cam.K, cam.lens)[0].reshape(-1, 2)
        assert np.abs(cam.project(pts) - theirs).max() < 1e-7
        assert np.abs(cam.undistort_px(cam.project(pts)) - cam.project_ideal(pts)).max() < 1e-8


def test_dlt_round_trip() -> None:
    cam = kiss_rig(2)[0]
    again = Camera.from_dlt(cam.dlt)
    assert np.allclose(again.K, cam.K) and np.allclose(again.R, cam.R, atol=1e-12)
    assert np.allclose(again.centre_mm, cam.centre_mm)
    assert np.array_equal(again.dlt, cam.dlt)  # the DLT is kept as given
    with pytest.raises(KisscalError, match="11 finite"):
        Camera.from_dlt(np.zeros(10), "x")
    with pytest.raises(KisscalError, match="4, 5, 8 or 12"):
        Camera(cam.K, cam.R, cam.t, np.zeros(6))


def test_lens_layers_compose_and_invert() -> None:
    """A grid polynomial, Kolahi's terms and a Brown lens on one camera: raw -> ideal ->
    raw round-trips, and a lab point's raw projection undistorts to its ideal one."""
    cam = kiss_rig(3)[0]
    lin, _ = camera_linearisation(Camera(cam.K, cam.R, cam.t, cam.lens * 0.5), cam.size_px)
    layered = Camera(
        cam.K, cam.R, cam.t, cam.lens * 0.5, "c", cam.size_px, lin, np.array([1e-8, 0, 0, 1e-6, 0])
    )
    raw = np.random.default_rng(4).uniform([0, 0], cam.size_px, (300, 2))
    assert np.abs(layered.distort_px(layered.undistort_px(raw)) - raw).max() < 1e-7
    pts = np.random.default_rng(5).uniform([-1000, -600, 0], [1000, 600, 2000], (50, 3))
    err = layered.undistort_px(layered.project(pts)) - layered.project_ideal(pts)
    assert np.abs(err).max() < 1e-7


def test_linearisation_polynomial_follows_the_lens_where_the_data_are() -> None:
    """Weighted on the calibration's image positions (the central 80 % here), the 30
    coefficients follow a 6-9 px barrel lens to 0.03 px there; the image corners, with a
    tenth of the weight, stay within 0.35 px."""
    for cam in kiss_rig(5):
        w, h = cam.size_px
        data = np.random.default_rng(2).uniform([0.1 * w, 0.1 * h], [0.9 * w, 0.9 * h], (1500, 2))
        lin, fit_max = camera_linearisation(cam, cam.size_px, data_px=data)
        err = np.linalg.norm(apply_linearisation(lin, data) - cam.undistort_px(data), axis=1)
        assert err.max() < 0.03 and fit_max < 0.35


@pytest.mark.parametrize("k", [4, 5, 8, 12])
def test_distort_each_is_distort_with_each_coefficient_moved_bit_for_bit(k):
    from kisscal.camera import distort_each

    rng = np.random.default_rng(k)
    xn = rng.uniform(-0.6, 0.6, (300, 2))
    lens = rng.normal(0, 0.05, k)
    moved = lens + rng.normal(0, 1e-3, k)
    rows = distort_each(lens, xn, moved)
    assert rows.shape == (k, 300, 2)
    for c in range(k):
        one = lens.copy()
        one[c] = moved[c]
        assert np.array_equal(rows[c], distort(one, xn))
