"""Re-tracking real C3D files from shuffled anonymous points (issue 26): the measurement of
``tests/io/c3d_acceptance.py`` on the committed fixtures (fixtures/real/c3d/)."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.io.c3d import read_c3d
from tests.io.c3d_acceptance import FIXTURES, distinct, retrack, shuffled


@pytest.mark.parametrize("name", ["pc_real.c3d", "sgi_int.c3d"])
def test_vicon_370_gait_comes_back_without_identity_switches(name):
    c3d = read_c3d(FIXTURES / name)
    r = retrack(c3d.xyz_mm, c3d.rate_hz)
    assert r.valid == 2976
    assert r.switches == 0
    assert r.coverage == 1.0  # every valid sample is held by a trajectory


def test_two_frames_keep_every_sample_as_unlabelled_trajectories():
    c3d = read_c3d(FIXTURES / "FP_Type3.c3d")
    r = retrack(c3d.xyz_mm, c3d.rate_hz)
    assert (r.valid, r.switches, r.coverage, r.trajectories) == (68, 0, 1.0, 34)


def test_the_measure_sees_a_switch():
    """The switch count is not blind: two markers exchanged half-way are one switch for
    a tracker that follows positions (the points, not the channels, are tracked)."""
    c3d = read_c3d(FIXTURES / "pc_real.c3d")
    xyz = distinct(c3d.xyz_mm)
    field, _, _ = shuffled(xyz)
    assert len(field) == np.isfinite(xyz[..., 0]).sum()
    swapped = xyz.copy()
    swapped[45:, [0, 1]] = swapped[45:, [1, 0]]  # channels exchange their markers
    r = retrack(swapped, c3d.rate_hz)
    assert r.switches >= 2
