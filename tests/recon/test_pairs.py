"""Two-camera markers: continuity, ambiguity, short trials, and 2-/3-camera rigs."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt.model import project
from kisscal.recon import ReconParams, reconstruct_trial
from kisscal.recon.epipolar import camera_centre_mm
from kisscal.recon.match import match_trial
from kisscal.recon.pairs import continuity_mm

from .rig import make_rig


def test_continuity_accepts_smooth_motion_and_refuses_a_jump() -> None:
    field = np.arange(7)
    xyz = np.column_stack([20.0 * field, 3.0 * field**2 / 10, np.zeros(7)])  # gentle curve
    score = continuity_mm(xyz, field, xyz, field, 100.0, 5.0)
    assert np.all(score <= 1.0)
    jumped = xyz.copy()
    jumped[3] += [0.0, 60.0, 0.0]
    assert np.isinf(continuity_mm(jumped[3:4], field[3:4], jumped, field, 100.0, 5.0)[0])


def test_a_midpoint_between_two_comoving_markers_is_not_a_trajectory() -> None:
    # A at f-1, the midpoint of A and B at f and B at f+1 are three collinear, equally spaced
    # positions; four positions are needed to tell them from a marker
    field = np.arange(6)
    a = np.column_stack([15.0 * field, np.zeros(6), np.zeros(6)])
    b = a + [0.0, 240.0, 0.0]
    pool = np.vstack([a, b])
    pool_field = np.r_[field, field]
    mid = (a + b) / 2
    assert np.all(np.isinf(continuity_mm(mid, field, pool, pool_field, 300.0, 20.0)))
    anchors = np.r_[np.zeros(6, bool), np.ones(6, bool)]
    # windows must hold an anchor when anchors are given: A's own track holds none
    assert np.all(np.isinf(continuity_mm(a, field, pool, pool_field, 300.0, 20.0, anchors)))
    assert np.all(continuity_mm(b, field, pool, pool_field, 300.0, 20.0, anchors) < 1e-9)


def _two_camera_trial(dlts: np.ndarray, xyz: np.ndarray, seen: list[list[int]]) -> tuple:
    """2D table of markers ``xyz`` (F, M, 3); camera c sees the markers in ``seen[c]``."""
    field, camera, uv, truth = [], [], [], []
    for c, markers in enumerate(seen):
        for f in range(len(xyz)):
            field += [f] * len(markers)
            camera += [c] * len(markers)
            truth += markers
            uv.append(project(dlts[c], xyz[f, markers]))
    return np.array(field), np.array(camera), np.concatenate(uv), np.array(truth)


def test_two_single_view_markers_on_one_epipolar_line_for_a_moment_make_no_marker() -> None:
    # camera 0 sees marker 0 only, camera 1 marker 1 only; marker 1 crosses the epipolar
    # line of marker 0 in field 5, where the pair looks like a marker for one field
    dlts = make_rig(3, n_cameras=2)
    n = 11
    x0 = np.array([0.0, 0.0, 900.0]) + np.arange(n)[:, None] * [20.0, 0.0, 0.0]
    x1_at5 = x0[5] + 0.4 * (x0[5] - camera_centre_mm(dlts[0]))  # on camera 0's ray
    x1 = x1_at5 + (np.arange(n) - 5)[:, None] * [0.0, 0.0, 40.0]
    xyz = np.stack([x0, x1], axis=1)
    field, camera, uv, _ = _two_camera_trial(dlts, xyz, [[0], [1]])
    marker = match_trial(field, camera, uv, dlts)
    assert not (marker >= 0).any()


def test_a_two_camera_rig_reconstructs_moving_markers() -> None:
    rng = np.random.default_rng(4)
    dlts = make_rig(4, n_cameras=2)
    n, m = 30, 6
    start = np.array([-600.0, -300.0, 200.0]) + rng.random((m, 3)) * [1200.0, 600.0, 1500.0]
    velocity = rng.normal(0.0, 15.0, (m, 3))
    xyz = start[None] + np.arange(n)[:, None, None] * velocity[None]
    field, camera, uv, truth = _two_camera_trial(dlts, xyz, [list(range(m))] * 2)
    uv += rng.normal(0.0, 0.05, uv.shape)
    pts = reconstruct_trial(field, camera, uv, dlts)
    assert len(pts) >= 0.98 * n * m
    rows = pts.blob_row
    assert np.all(truth[rows[:, 0]] == truth[rows[:, 1]]), "a pair of different markers"
    err = np.linalg.norm(pts.xyz_mm - xyz[pts.field, truth[rows[:, 0]]], axis=1)
    assert np.max(err) < 2.0


@pytest.mark.parametrize("n_fields", [1, 2])
def test_a_trial_too_short_for_a_trajectory_keeps_its_unambiguous_pairs(n_fields: int) -> None:
    dlts = make_rig(5, n_cameras=3)
    xyz = np.repeat(np.array([[[0.0, 0.0, 800.0], [300.0, 200.0, 1400.0]]]), n_fields, axis=0)
    field, camera, uv, _ = _two_camera_trial(dlts, xyz, [[0, 1], [0, 1], [0]])
    marker = match_trial(field, camera, uv, dlts)
    sizes = sorted(np.unique(marker[marker >= 0], return_counts=True)[1].tolist())
    assert sizes == [2] * n_fields + [3] * n_fields


def test_two_camera_markers_off() -> None:
    dlts = make_rig(4, n_cameras=2)
    xyz = np.repeat(np.array([[[0.0, 0.0, 800.0]]]), 5, axis=0)
    field, camera, uv, _ = _two_camera_trial(dlts, xyz, [[0], [0]])
    marker = match_trial(field, camera, uv, dlts, ReconParams(allow_two_camera=False))
    assert not (marker >= 0).any()
    assert (match_trial(field, camera, uv, dlts) >= 0).all()


@pytest.mark.parametrize("cameras", [(0, 1), (0, 1, 2)])
def test_two_and_three_camera_subsets_of_the_kiss_rig(cameras: tuple[int, ...]) -> None:
    """The synthetic session's own 2- and 3-camera rigs (``kisscal synth --cameras``)."""
    from .subsets import kiss_subsets

    for seed in (2, 4):
        (s,) = kiss_subsets(seed, [cameras], 120)
        assert s.recall_blobs >= 0.98, s
        assert s.ghost_fraction <= 0.02, s


def test_pairs_with_equal_scores_are_chosen_without_deadlock() -> None:
    # three blobs pairwise in contention (a triple the multi-camera matching left over),
    # all equally good: ranking ties by position in the blob list once looped for ever
    from kisscal.recon.pairs import _disjoint

    chosen = _disjoint(np.array([0, 0, 1, 4]), np.array([1, 2, 2, 6]), np.zeros(4))
    assert chosen.tolist() == [True, False, False, True]
