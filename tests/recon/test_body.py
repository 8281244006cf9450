"""Two-camera pairs taken by the body's rigid triangles (kisscal.recon.body)."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.errors import InputError
from kisscal.recon import ReconParams
from kisscal.recon.body import RigidTriangles, body_error, body_pairs

NAMES = ("RASI", "LASI", "SACR", "RKNE")
TEMPLATE = np.array([[0.0, 120, 0], [0, -120, 0], [-150, 0, 0], [0, 100, -450]])
SEGMENTS = (("RASI", "LASI"), ("RASI", "SACR"), ("LASI", "SACR"))


def _pelvis() -> np.ndarray:
    """The template's pelvis turned and moved into the lab."""
    turn = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])  # 90 degrees about Z
    return TEMPLATE[:3] @ turn.T + [1000.0, 500, 900]


def test_triangles_come_from_segments_linked_pairwise() -> None:
    t = RigidTriangles.from_marker_set(NAMES, TEMPLATE, SEGMENTS)
    assert len(t) == 3  # the pelvis, from each of its markers; the knee is in none
    assert np.allclose(sorted(t.d_jk), sorted([240.0, np.hypot(150, 120), np.hypot(150, 120)]))
    with pytest.raises(InputError, match="unknown markers"):
        RigidTriangles.from_marker_set(NAMES, TEMPLATE, (("RASI", "XX"),))


def test_a_point_keeping_the_pelvis_distances_fits_and_a_crossing_does_not() -> None:
    t = RigidTriangles.from_marker_set(NAMES, TEMPLATE, SEGMENTS)
    pelvis = _pelvis()
    known, known_field = pelvis[1:], np.array([4, 4])  # LASI and SACR known in field 4
    ghost = pelvis[0] + [0.0, 0.0, 150.0]  # where two other rays might cross
    err = body_error(
        np.array([pelvis[0], ghost, pelvis[0]]), np.array([4, 4, 5]), known, known_field, t
    )
    assert err[0] < 1e-6
    assert err[1] > 20.0
    assert np.isinf(err[2])  # field 5 has no known points


def test_body_pairs_takes_a_fitting_pair_unless_its_blobs_are_contested() -> None:
    t = RigidTriangles.from_marker_set(NAMES, TEMPLATE, SEGMENTS)
    pelvis = _pelvis()
    known, known_field = pelvis[1:], np.array([4, 4])
    a, b = np.array([0, 2, 4]), np.array([1, 3, 5])
    xyz = np.array([pelvis[0], pelvis[0] + [0.0, 0, 150], pelvis[0] + [0.0, 0, 3]])
    field = np.full(3, 4)
    none = np.zeros(3, dtype=bool)
    assert body_pairs(
        (a, b, xyz, field), none, (known, known_field), t, ReconParams()
    ).tolist() == [
        True,
        False,
        True,
    ]
    # the third pair sharing the first's blob: two pairs fit, neither is taken
    b2 = np.array([1, 3, 1])
    assert not body_pairs((a, b2, xyz, field), none, (known, known_field), t, ReconParams()).any()
