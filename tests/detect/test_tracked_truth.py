"""The real frames' tracked truth (tests/detect/real_acceptance.py) on moving points."""

from __future__ import annotations

import numpy as np

from tests.detect.real_acceptance import tracked, tracked_scores


def _moving_points() -> tuple[list[np.ndarray], np.ndarray]:
    """Five frames of 150 particles on parabolas in time, 0.05 px of centroid noise, a
    pair that touches in frame 2 only (3 px apart there, 15 px or more elsewhere) and a
    spot that stays put (the last)."""
    rng = np.random.default_rng(3)
    start = rng.uniform(0, 600, (150, 2))
    speed, pull = rng.uniform(-4, 4, (150, 2)), rng.uniform(-0.1, 0.1, (150, 2))
    start[:2] = [[300.0, 300.0], [303.0, 300.0]]  # the pair, at frame 2
    speed[:2], pull[:2] = [[1.5, 0.0], [1.5, -15.0]], 0.0
    start[-1], speed[-1], pull[-1] = [100.0, 500.0], 0.0, 0.0
    t = np.arange(5.0)[:, None, None] - 2.0
    truth = start + speed * t + pull * t**2
    return list(truth + rng.normal(0, 0.05, truth.shape)), truth[2]


def test_particles_are_tracked_to_where_they_touch() -> None:
    points, at_2 = _moving_points()
    found = tracked(points, 2)
    d = np.hypot(*(found[:, None] - at_2[None]).transpose(2, 0, 1)).min(axis=0)
    assert (d[:2] < 0.2).all(), d[:2]  # the touching pair: two particles, in place
    assert (d < 0.2).mean() > 0.8  # most particles (some pass too close to another)
    assert d[-1] > 1.0  # the spot that stays put is not a moving particle
    off = np.hypot(*(found[:, None] - at_2[None]).transpose(2, 0, 1)).min(axis=1)
    assert (off < 0.2).all(), off.max()  # no track where no particle is


def test_a_detector_that_merges_the_pair_misses_both() -> None:
    points, _ = _moving_points()
    merged = [p.copy() for p in points]
    merged[2] = np.vstack([merged[2][2:], merged[2][:2].mean(axis=0)])
    scores = tracked_scores(merged, points)
    assert scores["tracked"] > 300
    assert scores["openptv_tracked"] == scores["tracked"]
    assert scores["kisscal_tracked"] == scores["tracked"] - 2
