"""Pieces that are not the subject's do not define it: a still marker far from the body
(kisscal/tracking/labelling/core.py, issue 26)."""

import numpy as np

from kisscal.markersets import marker_set
from kisscal.tracking import TrackingParams, build_trajectories
from kisscal.tracking.labelling.core import far_from_body
from tests.tracking.markerset_acceptance import LOWER, walker_trial, wrong_labels

PIG = marker_set("plug-in-gait-lower", names=LOWER)


def _with_still_points(field: np.ndarray, xyz: np.ndarray, points: np.ndarray):
    """The observed points plus ``points`` (s, 3), still, seen in every field."""
    fields = np.unique(field)
    rng = np.random.default_rng(0)
    extra = points[None] + rng.normal(0.0, 0.5, (fields.size, points.shape[0], 3))
    return (
        np.r_[field, np.repeat(fields, points.shape[0])],
        np.r_[xyz, extra.reshape(-1, 3)],
    )


def test_still_points_far_from_the_walker_leave_every_name_right():
    # issue 26: a still channel 2.5 m from a walker and 430 mm below the floor set the
    # floor and the stature (1.95 m): nothing was named. Here one such point and one on
    # the floor, both beside the walk.
    truth, _, field, xyz = walker_trial(1, 1.7, 30.0, 1.0, 50.0)
    centre = np.nanmean(truth.reshape(-1, 3), axis=0)
    heading = np.radians(30.0)
    side = np.array([-np.sin(heading), np.cos(heading), 0.0])
    floor = np.nanmin(truth[..., 2])
    still = np.array(
        [
            [*(centre + 2500.0 * side)[:2], floor - 430.0],
            [*(centre - 1500.0 * side)[:2], floor],
        ]
    )
    field, xyz = _with_still_points(field, xyz, still)
    res = build_trajectories(field, xyz, TrackingParams(), marker_set=PIG, rate_hz=50.0)
    assert wrong_labels(res, truth, LOWER) == []
    unnamed = set(res.labelling.unlabelled)
    named = {label for t, label in enumerate(res.labels) if t not in unnamed}
    assert named == set(LOWER)
    assert abs(res.labelling.height_mm - 1700.0) <= 150.0


def test_far_from_body_tells_a_stray_piece_not_the_feet():
    truth, _, _, _ = walker_trial(2, 1.7, 0.0, 1.0, 50.0)
    window = truth[:, :50]
    stray = np.broadcast_to(window[0, 0] + [0.0, 2500.0, -400.0], (1, 50, 3))
    far = far_from_body(np.r_[window, stray])
    assert far.tolist() == [False] * len(LOWER) + [True]


def test_a_still_piece_beside_a_walk_is_told_but_no_foot_of_the_walker():
    # A still piece 1 m from the walk is not far from the body; it stays put while the
    # body walks on. The walker's feet stand still in stance, but swing in every 1 s.
    for speed in (0.6, 1.0, 1.4):
        truth, _, _, _ = walker_trial(3, 1.6, 45.0, speed, 50.0)
        for start in range(0, truth.shape[1] - 50, 25):
            window = truth[:, start : start + 50]
            assert not far_from_body(window).any()
        window = truth[:, 50:100]
        still = np.broadcast_to(np.nanmean(window[0], axis=0) + [700.0, -700.0, 0.0], (1, 50, 3))
        assert far_from_body(np.r_[window, still])[-1] == (speed >= 1.0)
