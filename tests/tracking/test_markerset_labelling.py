"""Labelling from a shipped marker set alone, and its parts (stature, subject template).

The full table over 32 trials is ``python -m tests.tracking.markerset_acceptance``.
"""

import numpy as np
import pytest

from kisscal.markersets import marker_set
from kisscal.tracking import TrackingParams, build_trajectories
from kisscal.tracking.blending import blend_tracks
from kisscal.tracking.labelling.result import Labelling
from kisscal.tracking.labelling.state import segment_mask
from kisscal.tracking.labelling.subject import (
    HEIGHTS_MM,
    _floor_seen,
    estimate_height,
    fit_template,
)
from kisscal.tracking.rigid import refine_by_swaps
from kisscal.tracking.tracker import track_points
from kisscal.tracking.tracks import make_tracks
from tests.tracking._eval import score
from tests.tracking.markerset_acceptance import LOWER, walker_trial, wrong_labels

PIG = marker_set("plug-in-gait-lower", names=LOWER)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("seed", "height", "heading", "rate"),
    [(0, 1.52, 250.0, 50.0), (1, 1.88, 35.0, 100.0)],
)
def test_set_alone_labels_a_walker_of_any_stature_and_heading(seed, height, heading, rate):
    truth, visible, field, xyz = walker_trial(seed, height, heading, 1.1, rate)
    res = build_trajectories(field, xyz, TrackingParams(), marker_set=PIG, rate_hz=rate)
    s = score(res, truth, visible, LOWER)
    assert s.labels_correct == 15 and s.identity_switches == 0
    assert res.labelling.unlabelled == () and res.labelling.certain
    assert abs(res.labelling.height_mm - 1000 * height) <= 60.0
    assert res.labelling.sides_from == "anatomy"


def test_stature_is_found_from_the_average_pose():
    _, _, field, xyz = walker_trial(2, 1.62, 140.0, 1.0, 50.0)
    params = TrackingParams(label_window_fields=50)
    tracks = blend_tracks(track_points(field, xyz, params), params)
    height, partial = estimate_height(tracks, PIG, params)
    assert height in HEIGHTS_MM and abs(height - 1620.0) <= 60.0 and not partial


@pytest.mark.parametrize("seed, speed", [(0, 1.4), (1, 1.6)])
def test_a_lower_body_walking_fast_stands_at_its_own_stature_on_the_full_body_set(seed, speed):
    # The stature's average pose keeps the lab's heights (issue 26): with each field's
    # vertical shift fitted, the pelvis sank and a 1.75 m lower body stood at 1.65 m.
    _, _, field, xyz = walker_trial(seed, 1.75, 90.0 * seed, speed, 100.0)
    params = TrackingParams(label_window_fields=100)
    tracks = blend_tracks(track_points(field, xyz, params), params)
    height, partial = estimate_height(tracks, marker_set("plug-in-gait-full"), params)
    assert partial and abs(height - 1750.0) <= 50.0


def test_a_child_walker_is_labelled_at_its_own_stature():
    # A 1.0 m child with the whole set: its distances fit no adult template (issue 26: the
    # estimate stuck at 1.40 m, the range's bound, and every name was doubted).
    truth, _, field, xyz = walker_trial(3, 1.0, 140.0, 0.8, 50.0)
    res = build_trajectories(field, xyz, TrackingParams(), marker_set=PIG, rate_hz=50.0)
    assert abs(res.labelling.height_mm - 1000.0) <= 60.0
    assert wrong_labels(res, truth, LOWER) == []
    assert res.labelling.certain and res.labelling.flagged == ()


def test_subject_template_takes_the_measured_rigid_lengths():
    template = PIG.scaled(1700.0).template_mm
    rng = np.random.default_rng(0)
    # Trajectories: the template 10 % longer in its shank and foot (a moving body would do).
    pos = np.repeat((template * [1.0, 1.0, 1.0])[:, None, :], 50, axis=1)
    i, j = LOWER.index("LTIB"), LOWER.index("LANK")
    pos[j] = pos[i] + 1.1 * (pos[j] - pos[i])
    pos += rng.normal(0, 0.5, pos.shape)
    fitted = fit_template(pos, template, segment_mask(LOWER, PIG.segments))
    measured = np.linalg.norm(pos[i, 0] - pos[j, 0])
    assert np.linalg.norm(fitted[i] - fitted[j]) == pytest.approx(measured, abs=2.0)
    others = [k for k in range(len(LOWER)) if k not in (i, j)]
    assert np.abs(fitted[others] - template[others]).max() < 5.0  # the rest barely moves


def test_swap_search_with_a_per_track_cost_follows_it():
    """Two tracks whose distances cannot tell them apart (symmetric), told apart by the
    unary cost alone; and the closed-form changes equal the recomputed cost changes."""
    template = np.array([[0.0, 0, 0], [0, 100, 0], [0, -100, 0], [0, 0, 300], [0, 0, -300]])
    tdist = np.linalg.norm(template[:, None] - template[None], axis=2)
    d = tdist.copy()
    w = np.ones_like(d)
    np.fill_diagonal(w, 0)
    start = np.arange(5)
    assert np.array_equal(refine_by_swaps(d, w, tdist, start), start)  # already optimal
    unary = np.zeros((5, 5))
    unary[1, 1] = unary[2, 2] = 50.0  # track 1 prefers name 2, track 2 name 1
    out = refine_by_swaps(d, w, tdist, start, unary=unary)
    np.testing.assert_array_equal(out, [0, 2, 1, 3, 4])


def test_wrong_labels_of_a_full_body_set_on_foreign_markers_are_flagged():
    """walking5's 34 markers (16 of Plug-in Gait full body, 18 of another set), every
    fifth field, named from plug-in-gait-full alone: no label may be wrong and certain."""
    from tests.tracking.markerset_acceptance import _walking5

    labels, xyz, rate, field, points = _walking5(step=5)
    full = marker_set("plug-in-gait-full")
    res = build_trajectories(field, points, TrackingParams(), marker_set=full, rate_hz=rate)
    expected = {n: full.aliases.get(n, n) for n in labels}
    wrong = wrong_labels(res, xyz.transpose(1, 0, 2), labels)
    silent = [
        (label, own)
        for label, own in wrong
        # a label is wrong when it is not the marker's name in the set (LLFC is LKNE)
        if expected[own] in full.names
        and label != expected[own]
        and label not in res.labelling.flagged
    ]
    assert silent == []


def test_names_held_with_none_near_the_floor_stand_on_an_assumed_floor():
    # shd01 (BTK), an upper body: its heights were judged from the lab's Z = 0, and its
    # head, turned 60 degrees on the trunk, was named a quarter turn round by its place.
    full = marker_set("plug-in-gait-full")

    def seen(*names: str) -> bool:
        k = np.arange(len(names))
        tracks = make_tracks(0 * k, k, np.zeros((k.size, 3)), np.zeros((k.size, 3)), 0 * k, k)
        return _floor_seen(Labelling(tracks, names, True, (), (), 0.0), full, TrackingParams())

    assert not seen("LFHD", "C7", "LASI", "RWRA")  # the lowest, the wrist, 859 mm up
    assert seen("LFHD", "LASI", "LANK") and seen("RTOE")
