"""Re-tracking real C3D files from shuffled anonymous points (issue 26): the measurement of
``tests/io/c3d_acceptance.py`` on the committed fixtures (fixtures/real/c3d/)."""

from __future__ import annotations

from collections.abc import Callable
from functools import cache

import numpy as np
import pytest

from kisscal.io.c3d import read_c3d
from kisscal.tracking import TrackingParams
from tests.io.c3d_acceptance import (
    FIXTURES,
    Retrack,
    distinct,
    file_relabels,
    retrack,
    shared_samples,
    shuffled,
    system_fills,
)


@pytest.fixture(scope="module")
def retracked() -> Callable[[str], Retrack]:
    """``retracked(name)``: the fixture file ``name`` re-tracked with the default parameters,
    once for the module (three tests read the push-rim stroke's, two the serve's; the
    stroke's takes some 27 s). Module-scoped: tests/conftest.py keeps the module's tests on
    one test process, so no two processes re-track the same file."""

    @cache
    def get(name: str) -> Retrack:
        c3d = read_c3d(FIXTURES / name)
        return retrack(c3d.xyz_mm, c3d.rate_hz)

    return get


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
    # The channels' names exchange their markers: the file's own switches.
    assert r.relabels == r.switches


def test_a_jump_to_another_marker_is_not_the_files_rename():
    """A channel that ends while another appears away from its path (BTS.c3d's SCR1 ends,
    SCR2 appears 58 mm off it, the two usually 62 mm apart) is two markers: a tracker that
    joins them made the switch, not the file; the same channel appearing on the path is
    the file's rename."""
    t = np.arange(10.0)
    xyz = np.full((10, 2, 3), np.nan)
    xyz[:, 0] = np.stack([2.0 * t, 0 * t, 0 * t], axis=1)
    xyz[:, 1] = xyz[:, 0] + [0.0, 62.0, 0.0]  # usually 62 mm apart
    xyz[5:, 0] = np.nan
    xyz[:5, 1] = np.nan
    xyz[:2, 1] = xyz[:2, 0] + [0.0, 62.0, 0.0]
    before, after, a, b = np.array([4]), np.array([5]), np.array([0]), np.array([1])
    elsewhere = xyz.copy()
    elsewhere[5, 1] = xyz[4, 0] + [0.0, 58.0, 0.0]
    assert file_relabels(elsewhere, before, after, a, b) == 0
    on_path = xyz.copy()
    on_path[5, 1] = xyz[4, 0] + [2.0, 0.0, 0.0]
    assert file_relabels(on_path, before, after, a, b) == 1


def test_a_name_swapped_for_a_frame_or_leaving_its_path_is_the_files_rename():
    """Two names swapped for one frame (sample_OptiTrack_walking's foot markers 5 and 3,
    96 mm apart, frame 1952): the tracker that follows both markers makes four switches,
    all the file's, the swap's giving back too. A name that leaps off its path (gait9's
    "r mall": 28 then 66 mm a field while it moved 8) while a channel usually 431 mm away
    takes the path up two frames later is the file's rename; a tracker that jumps
    between two smooth markers 30 mm apart is not."""
    t = np.arange(14.0)
    path = np.stack([8.0 * t, 0.1 * t**2, 0 * t], axis=1)
    xyz = np.stack([path, path + [0.0, 96.0, 0.0]], axis=1)
    xyz[6] = xyz[6, ::-1]
    before, after = np.array([5, 6, 5, 6]), np.array([6, 7, 6, 7])
    a, b = np.array([0, 1, 1, 0]), np.array([1, 0, 0, 1])
    assert file_relabels(xyz, before, after, a, b) == 4
    left = np.stack([path, path + [0.0, 431.0, 0.0]], axis=1)
    left[7:, 0] = path[7:] + np.where(t[7:, None] > 7, [0.0, -90.0, 0.0], [0.0, -28.0, 0.0])
    left[5:8, 1] = np.nan
    left[8:, 1] = path[8:]
    one = (np.array([6]), np.array([8]), np.array([0]), np.array([1]))
    assert file_relabels(left, *one) == 1
    jump = np.stack([path, path + [0.0, 30.0, 0.0]], axis=1)
    assert file_relabels(jump, np.array([6]), np.array([7]), *one[2:]) == 0


def test_the_systems_linear_fill_is_not_the_marker():
    """A channel whose samples for a few frames lie on the straight line between its
    samples either side (the writing system's gap fill) while the marker's measurement is
    written under another name (the tennis serve's RFRM in frames 190-192, its marker
    under RELB at 190): the file renamed the marker; a measured sample in the same place
    (noisy, off the line) keeps it the tracker's switch."""
    rng = np.random.default_rng(1)
    t = np.arange(12.0)
    path = np.stack([30.0 * t, 2.0 * t**2, 0 * t], axis=1)  # a marker accelerating
    xyz = np.full((12, 2, 3), np.nan)
    xyz[:, 0] = path + rng.normal(0.0, 0.2, path.shape)
    xyz[:, 1] = xyz[:, 0] + [0.0, 100.0, 0.0]
    # Frames 6-8: channel 0 filled by a straight line from frame 5 to frame 9, the
    # marker's measurement written under channel 1 at frame 6 (channel 1 then missing).
    xyz[6:9, 0] = xyz[5, 0] + (xyz[9, 0] - xyz[5, 0]) * ((t[6:9] - 5.0) / 4.0)[:, None]
    xyz[6, 1] = path[6] + [0.1, -0.1, 0.0]
    fills = system_fills(xyz)
    assert fills[6:9, 0].all() and fills.sum() == 3
    before, after, a, b = np.array([5]), np.array([6]), np.array([0]), np.array([1])
    assert file_relabels(xyz, before, after, a, b) == 0  # the fill stands near the path
    assert file_relabels(xyz, before, after, a, b, fills) == 1
    measured = xyz.copy()
    measured[6:9, 0] += rng.normal(0.0, 0.2, (3, 3))
    assert not system_fills(measured).any()


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
    ("name", "most", "off"),
    [
        ("kinematics_tennis_serve.c3d", 8, {"gate_error_factor": 0.0}),
        # the glove's triads are rigid: the cluster's cut (cluster.broken) alone keeps them
        # too (0 switches without the widening), so both are turned off
        (
            "kinematics_racing_propulsion.c3d",
            10,
            {"gate_error_factor": 0.0, "cluster_radius_mm": 0.0},
        ),
    ],
)
def test_fast_limbs_keep_identities_with_gates_widened_by_their_errors(name, most, off, retracked):
    """A serve's hand at 50 Hz (to 13 m/s) and a push-rim stroke's glove triads at 70 Hz
    (41 mm apart, accelerating by more than that per field): the gates widened by each
    track's own recent prediction errors keep far more identities than without (measured
    5 and 6 switches against 52 and 85, ambiguous fields cut; since the cluster's cut, the
    stroke 0 against 15 without it either). Both files are committed fixtures."""
    c3d = read_c3d(FIXTURES / name)
    widened = retracked(name)
    plain = retrack(c3d.xyz_mm, c3d.rate_hz, params=TrackingParams(**off))
    assert widened.coverage == plain.coverage == 1.0
    assert widened.switches <= most
    assert plain.switches > 3 * widened.switches


@pytest.mark.slow
def test_ambiguous_assignments_are_cut_for_blending_to_judge(retracked):
    """The push-rim glove triads (70 Hz, 43 mm apart): where another one-to-one choice
    explains a field almost as well, the tracks are cut and blending joins the pieces from
    both sides; the identity switches the tracker makes (the file's own renames apart) fall
    from 16 to 6 at the same coverage (measured)."""
    c3d = read_c3d(FIXTURES / "kinematics_racing_propulsion.c3d")
    cut = retracked("kinematics_racing_propulsion.c3d")
    guessed = retrack(c3d.xyz_mm, c3d.rate_hz, params=TrackingParams(ambiguity_margin=0.0))
    assert cut.coverage == guessed.coverage == 1.0
    assert cut.switches - cut.relabels <= 8
    assert 2 * (cut.switches - cut.relabels) < guessed.switches - guessed.relabels


@pytest.mark.slow
def test_a_track_with_a_rival_nearly_as_near_is_cut():
    """The push-rim glove: where a track's marker vanishes, its prediction misses the
    neighbour by about the markers' spacing (52-82 mm, the next point 1.1-1.3 times as far):
    cut there (``rival_ratio``), the tracker's identity switches fall from 2 to 0 at the
    same coverage (measured). Both without the cluster's carry (``cluster_radius_mm``),
    which on this glove keeps every identity with or without the cut; the control also
    keeps every first step (``first_step_ratio`` 0), as ``rival_ratio`` 0 did before that
    ratio was its own."""
    c3d = read_c3d(FIXTURES / "kinematics_racing_propulsion.c3d")
    alone = TrackingParams(cluster_radius_mm=0.0)
    cut = retrack(c3d.xyz_mm, c3d.rate_hz, params=alone)
    taken = retrack(
        c3d.xyz_mm, c3d.rate_hz, params=alone.replace(rival_ratio=0.0, first_step_ratio=0.0)
    )
    assert cut.coverage == taken.coverage == 1.0
    assert cut.switches - cut.relabels <= 2
    assert 3 * (cut.switches - cut.relabels) < taken.switches - taken.relabels


@pytest.mark.slow
@pytest.mark.parametrize(
    "name", ["kinematics_tennis_serve.c3d", "kinematics_racing_propulsion.c3d"]
)
def test_fast_limbs_switch_only_where_the_file_renames(name, retracked):
    """The serve (50 Hz) and the push-rim stroke (70 Hz) re-tracked: every identity switch
    left is the file's own rename. The serve's last one was a piece of two points whose
    second was a guess (elbow and upper arm 121 and 129 mm from the elbow's point: split
    off, :func:`~kisscal.tracking.tracker.split_ambiguous_first_steps`); the stroke's a join
    across frames 280-283 another glove marker, seen in the gap, contested."""
    r = retracked(name)
    assert r.coverage == 1.0
    assert r.switches == r.relabels


def test_a_sample_two_markers_share_is_no_switch_either_way():
    """Two markers 3 mm apart in one field are one sample (kept under one name): a track
    that enters or leaves it under the other name made no switch; a change between
    separate samples still is one."""
    t = np.arange(10.0)
    xyz = np.zeros((10, 2, 3))
    xyz[:, :, 0] = 2.0 * t[:, None]
    xyz[:, 1, 1] = 20.0
    xyz[5, 1, 1] = 3.0  # marker 1 touches marker 0 in field 5
    clean = distinct(xyz)
    assert np.isnan(clean[5, 1]).all() and np.isfinite(clean[5, 0]).all()
    before, after = np.array([4, 5, 3, 6]), np.array([5, 6, 4, 7])
    a, b = np.array([1, 0, 1, 0]), np.array([0, 1, 0, 1])
    assert shared_samples(xyz, clean, before, after, a, b).tolist() == [True, True, False, False]
