"""Small labs (issue 27): a 4-camera webcam-class rig, truth-level scenario with blobs lost
beside the body's occlusions, reconstructed and tracked with default settings, against
truth. The full table over held-out seeds: ``python -m tests.tracking.few_cameras_acceptance``.
"""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.tracking import TrackingParams
from tests.tracking.few_cameras_acceptance import rig_trial, score_trial, track_trial


@pytest.fixture(scope="module")
def lowcost():
    return rig_trial("lowcost", 1)


@pytest.fixture(scope="module")
def scored(lowcost):
    return score_trial(lowcost)


def test_four_cameras_keep_markers_that_two_cameras_see(lowcost, scored):
    s = scored
    n2 = lowcost.visible.sum(axis=2) == 2
    assert n2.sum() > 500  # the scenario has long two-camera stretches
    assert s.recall2 >= 0.97
    assert s.ghost_fraction <= 0.005


def test_four_cameras_name_every_marker_and_fill_from_the_body(lowcost, scored):
    s = scored
    assert s.labelled == 15 and s.switches == 0
    assert s.filled_by["filled_rigid"] > 0 and s.filled_by["filled_pattern"] > 0
    assert s.rmse_filled_mm <= 3.5
    assert s.coverage_mean >= 0.985
    # the spline alone leaves the longer gaps open
    spline_only = score_trial(lowcost, TrackingParams(max_body_fill_fields=5))
    assert spline_only.coverage_mean < s.coverage_mean - 0.01
    assert spline_only.filled_by["filled_rigid"] == spline_only.filled_by["filled_pattern"] == 0


def test_without_two_camera_points_alone_four_cameras_lose_markers(lowcost, monkeypatch):
    import tests.tracking.few_cameras_acceptance as acceptance
    from kisscal.recon import ReconParams

    monkeypatch.setattr(acceptance, "RECON", [ReconParams(two_camera_alone_max_cameras=3)])
    strict = acceptance.rig_trial("lowcost", 1)
    n2 = strict.visible.sum(axis=2) == 2
    assert strict.found[n2].mean() < lowcost.found[n2].mean() - 0.03
    assert np.isfinite(strict.found[n2].mean())


@pytest.mark.parametrize("seed, merge", [(2, None), (9, None), (9, "first")])
def test_three_cameras_never_name_wrongly(seed, merge):
    """kiss preset, 3 cameras: pieces are short and the first window's average pose may
    match no body; then tracks stay M1, M2, ..., never a name on the wrong marker.
    Seed 9 also on the merged-blob scenario it was written for: with merged blobs at
    their centroid a 7-field ankle piece was body-fitted as the heel (7 switches) until
    the foot contest judged each piece by its distances to the shank and the foot."""
    s = score_trial(rig_trial("kiss", seed, 3, merge))
    assert s.switches == 0


def test_three_cameras_name_markers_from_a_window_where_pieces_are_whole():
    """kiss preset, 3 cameras, seed 2: no window as long as the trial holds three pieces
    seen whole, so the first average pose used to match nothing and every track stayed
    M1, M2, ...; a shorter window holds most markers whole, and every marker two cameras
    see long enough is named, none wrongly."""
    s = score_trial(rig_trial("kiss", 2, 3))
    assert s.labellable >= 12
    assert s.labelled >= s.labellable and s.switches == 0
    assert s.coverage_mean >= 0.95


def test_single_camera_fill_moves_filled_samples_onto_the_ray_and_they_get_closer(lowcost, scored):
    """The same trial without the unused blobs: fewer samples filled (the marker's own
    blobs place it where the body cannot), less of each span covered, no closer."""
    body_only = score_trial(lowcost, rays=False)
    assert sum(scored.filled_by.values()) > sum(body_only.filled_by.values())
    assert scored.coverage_mean > body_only.coverage_mean
    # the body alone fills this trial to 1.83 mm RMS since the hinge fill (2.54 before);
    # with the rays 2.29, most of it three fields of the right heel bridged to a sample
    # the chain placed 20 mm off on a blob merged with the left heel's
    assert scored.rmse_filled_mm < max(body_only.rmse_filled_mm, 2.5)


def test_four_cameras_name_a_leg_whose_pieces_each_cover_half_the_trial():
    """lowcost preset, seed 303 (held out, looked at for this): no long window holds a
    piece of the right leg whole, so the first window named the pelvis and left leg
    only; shorter windows that agree with those names name the right leg."""
    s = score_trial(rig_trial("lowcost", 303))
    assert s.labelled == 15 and s.switches == 0
    assert s.coverage_mean >= 0.94


def test_four_cameras_keep_the_names_when_ghost_pieces_are_withdrawn():
    """lowcost preset, seed 301 (held out), merged blobs at their centroid: withdrawing
    the two-camera pieces whose rays other trajectories claim made the first window's
    median fit prefer the left ankle and toe exchanged by 5 %, and the left leg lost
    its names (10/15, 646 switches); the pair's direction keeps them."""
    s = score_trial(rig_trial("lowcost", 301))
    assert s.labelled == 15 and s.switches == 0
    assert s.coverage_min >= 0.95


def test_three_cameras_fill_a_foot_that_one_camera_sees_from_its_rays():
    """kiss preset, 3 cameras, seed 311 (held out, looked at for this): the right heel
    and ankle are seen by one camera for 14 fields while the toe is measured; the two
    rays and the foot's three lengths place the heel (it was left open: 96.1 %)."""
    s = score_trial(rig_trial("kiss", 311, 3))
    assert s.coverage_min >= 0.995
    assert s.rmse_filled_mm < 3.0
    assert s.switches == 0


def test_three_cameras_name_an_ankle_and_a_knee_that_one_camera_sees():
    """kiss preset, 3 cameras, seed 304: the right ankle and knee are never seen by two
    cameras (one camera sees each all trial), so no 3D point and no piece took their
    names (13/15). Placed on their rays by their mirror images' lengths, the ankle by
    heel, toe and tibia, the knee by tibia and the ankle placed so, they are named, every
    sample near its marker, and no other name moves."""
    trial = rig_trial("kiss", 304, 3)
    res = track_trial(trial)
    assert {"RANK", "RKNE"} <= set(res.labels) and not res.labelling.missing
    for name in ("RANK", "RKNE"):
        rows = np.asarray(res.labels)[res.tracks.track] == name
        truth = trial.truth[res.tracks.field[rows], trial.names.index(name)]
        err = np.linalg.norm(res.tracks.xyz_mm[rows] - truth, axis=1)
        assert rows.sum() >= 30 and np.sqrt(np.mean(err**2)) < 2.5 and err.max() < 5.0
    s = score_trial(trial)
    assert s.labelled == 15 and s.switches == 0


@pytest.mark.slow
def test_three_modern_cameras_name_every_marker_once_per_field():
    """modern preset, 3 cameras, seed 409 (held out; the few-camera table's row): every
    marker is named, no measured sample is nearer another marker than its name's, no
    track holds two samples in one field, and the names cover most of each marker's span
    (92 % at the least at present)."""
    trial = rig_trial("modern", 409, 3)
    res = track_trial(trial)
    tr = res.tracks
    held = np.unique(np.stack([tr.track, tr.field]), axis=1).shape[1]
    assert held == tr.field.size
    s = score_trial(trial)
    assert s.labelled == s.n_markers == 15 and s.switches == 0
    assert s.coverage_min >= 0.9
    assert s.rmse_filled_mm < 3.0


@pytest.mark.slow
def test_three_cameras_put_back_a_pelvis_whose_short_piece_was_named_with_it():
    """kiss preset, 3 cameras, seed 442 (held out): from field 230 the sacrum's pieces
    and the right ASIS's were named the other way round, a 7-field sacrum piece with
    them; the walk put the long pieces right but the short one, left with the ASIS's
    name in a field of the ASIS's piece, refused the exchange (224 identity switches,
    coverage min 0 %). The short piece goes back with the exchange."""
    s = score_trial(rig_trial("kiss", 442, 3))
    assert s.switches == 0
    assert s.coverage_min >= 0.995
    assert s.rmse_filled_mm < 3.0


@pytest.mark.slow
@pytest.mark.parametrize("seed", [443, 444])
def test_three_cameras_name_a_toe_by_the_trajectory_it_continues(seed):
    """modern preset, 3 cameras, seeds 443 and 444: a toe seen again by two cameras
    while its foot's other markers are hidden was named the heel by the body fit (the
    standing template puts a walking toe near the heel's place), 23 and 24 identity
    switches and on 443 a filled RMS of 6.9 mm; seen from the shank it steps on from
    the toe's trajectory, not the heel's."""
    s = score_trial(rig_trial("modern", seed, 3))
    assert s.labelled == 15 and s.switches == 0
    assert s.rmse_filled_mm < 3.0


@pytest.mark.slow
def test_three_cameras_give_an_asis_pointing_backwards_the_free_pelvis_name():
    """kiss preset, 3 cameras, seed 468 (held out at stop 59): a short window without the
    sacrum's piece named the left ASIS sacrum (its distances to the walking right leg fit
    the sacrum's standing ones better); beside the right ASIS it pointed backwards, and
    exchanging the two made two wrong names of one (590 identity switches, filled RMS
    84 mm). Given the free sacrum name's alternative, the ASIS keeps its own."""
    s = score_trial(rig_trial("kiss", 468, 3))
    assert s.switches == 0
    assert s.rmse_filled_mm < 3.0


@pytest.mark.slow
def test_three_cameras_keep_the_sacrum_between_its_pieces_and_the_heel_behind_the_toe():
    """kiss preset, 3 cameras, seed 470 (held out at stop 60): the walk from one heel's
    step alone exchanged that foot's heel and toe in the trial's last 25 fields, and a
    16-field sacrum piece named an ASIS by the path it continued kept that name when the
    pieces on both sides were renamed (the standing template's distances to the walking
    legs fitted the ASIS better): 62 identity switches, filled RMS 32.6 mm."""
    s = score_trial(rig_trial("kiss", 470, 3))
    assert s.labelled == 15 and s.switches == 0
    assert s.rmse_filled_mm < 3.0
