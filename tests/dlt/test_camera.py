"""DLT <-> K, R, centre (Woltring & Huiskes eq. 15) and Hatze's constraint."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kisscal.dlt import compose_dlt, decompose_dlt, hatze_violation, project
from kisscal.dlt.model import dlt_from_krt

LEVEL_ALONG_Y = np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])  # looking along +Y
LEVEL_ALONG_MINUS_Y = np.array([[-1.0, 0, 0], [0, 0, -1], [0, -1, 0]])  # rotation by 180 deg


@pytest.mark.parametrize(
    "R",
    [
        LEVEL_ALONG_Y,
        LEVEL_ALONG_MINUS_Y,
        Rotation.from_euler("xyz", [100, 20, -30], degrees=True).as_matrix(),
    ],
)
@pytest.mark.parametrize("centre", [[700.0, -4000, 1100], [700.0, 5000, 1100]])
def test_decompose_inverts_compose(R, centre):
    K = np.array([[720.0, 1.5, 380], [0, 374, 150], [0, 0, 1]])
    L = compose_dlt(K, R, centre)
    K2, R2, C2 = decompose_dlt(L)
    np.testing.assert_allclose(K2, K, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(R2, R, atol=1e-12)
    np.testing.assert_allclose(C2, centre, atol=1e-7)
    np.testing.assert_allclose(compose_dlt(K2, R2, C2), L, rtol=1e-9, atol=1e-15)


def test_lab_origin_behind_the_camera_keeps_the_true_pose():
    # Camera at y = +5000 looking along +Y: the lab origin is behind it, P[2, 3] < 0.
    K = np.diag([700.0, 364, 1])
    K[:2, 2] = [376, 145]
    C = np.array([700.0, 5000, 1000])
    L = dlt_from_krt(K, LEVEL_ALONG_Y, -LEVEL_ALONG_Y @ C)
    K2, R2, C2 = decompose_dlt(L)
    np.testing.assert_allclose(R2, LEVEL_ALONG_Y, atol=1e-12)
    np.testing.assert_allclose(C2, C, atol=1e-7)
    np.testing.assert_allclose(np.diag(K2), [700, 364, 1])


def test_hatze_violation_measures_skew():
    R = Rotation.from_euler("xyz", [95, 5, 40], degrees=True).as_matrix()
    C = [100.0, -3000, 900]
    K = np.array([[700.0, 0, 380], [0, 360, 150], [0, 0, 1]])
    assert abs(hatze_violation(compose_dlt(K, R, C))) < 1e-14
    K[0, 1] = 0.7  # skew of 0.1 % of fu
    # -skew fv / (|L1..3| |L5..7|) with |L1..3| = sqrt(fu^2 + s^2 + u0^2) for unit depth
    expected = -0.7 * 360 / (np.sqrt(700**2 + 0.7**2 + 380**2) * np.hypot(360, 150))
    assert hatze_violation(compose_dlt(K, R, C)) == pytest.approx(expected, rel=1e-9)


def test_principal_point():
    K = np.array([[700.0, 0, 380], [0, 360, 150], [0, 0, 1]])
    L = compose_dlt(K, LEVEL_ALONG_Y, [0.0, -3000, 1000])
    # The principal point is the image of points on the optical axis
    np.testing.assert_allclose(project(L, [0.0, 500, 1000]), [380, 150])
