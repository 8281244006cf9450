"""Re-tracking real C3D files from shuffled anonymous points (issue 26): the measurement of
``tests/io/c3d_acceptance.py`` on the committed fixtures (fixtures/real/c3d/)."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.io.c3d import read_c3d
from kisscal.tracking import TrackingParams
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
    assert r.relabels == 0  # both channels go on: not the file renaming one marker


def test_a_marker_the_file_renames_is_a_switch_the_file_makes():
    """A marker whose samples move from one channel to a new one half-way (as OptiTrack
    relabels a static marker): the trajectory follows the marker, one switch, and it is
    the file's own (``relabels``)."""
    c3d = read_c3d(FIXTURES / "pc_real.c3d")
    xyz = distinct(c3d.xyz_mm)
    renamed = np.concatenate([xyz, np.full_like(xyz[:, :1], np.nan)], axis=1)
    renamed[45:, -1] = renamed[45:, 0]
    renamed[45:, 0] = np.nan
    r = retrack(renamed, c3d.rate_hz)
    assert (r.switches, r.relabels, r.coverage) == (1, 1, 1.0)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "most"),
    [("kinematics_tennis_serve.c3d", 12), ("kinematics_racing_propulsion.c3d", 20)],
)
def test_fast_limbs_keep_identities_with_gates_widened_by_their_errors(name, most):
    """A serve's hand at 50 Hz (to 13 m/s) and a push-rim stroke's glove triads at 70 Hz
    (41 mm apart, accelerating by more than that per field): the gates widened by each
    track's own recent prediction errors keep far more identities than without (measured
    10 and 17 switches against 63 and 114). Both files are committed fixtures."""
    c3d = read_c3d(FIXTURES / name)
    widened = retrack(c3d.xyz_mm, c3d.rate_hz)
    plain = retrack(c3d.xyz_mm, c3d.rate_hz, params=TrackingParams(gate_error_factor=0.0))
    assert widened.coverage == plain.coverage == 1.0
    assert widened.switches <= most
    assert plain.switches > 3 * widened.switches
