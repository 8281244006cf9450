"""Overlapping markers (Shafiq et al. 2001, sections 2.3.2-2.3.3) on rendered pairs."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.detect import detect_blobs
from tests.detect.conftest import ASPECT, KISS, render


def _pairs(rng: np.random.Generator, angle_deg: tuple[float, float], n: int = 30):
    """n well-separated pairs of equal markers, centres 1-2 radii apart (round units).

    Pairs fill every other lattice cell; single markers fill the rest, so that, as in a
    real field, most groups are single markers (the spot growth is estimated from them).
    """
    gx, gy = np.meshgrid(np.linspace(40, 700, 10), np.linspace(30, 260, 6))
    first = np.column_stack([gx.ravel(), gy.ravel()])[: 2 * n : 2]
    radius = rng.uniform(3.0, 5.0, n)
    spacing = rng.uniform(1.0, 2.0, n) * radius
    angle = np.radians(rng.uniform(*angle_deg, n))
    second = first + np.column_stack([spacing * np.cos(angle), spacing * np.sin(angle) / ASPECT])
    singles = np.column_stack([gx.ravel(), gy.ravel()])[1 : 2 * n : 2] + 3.0
    single_r = rng.uniform(2.0, 5.0, len(singles))
    return np.vstack([first, second, singles]), np.r_[radius, radius, single_r]


def _recall(blobs, truth, radius):
    valid = blobs.valid_only()
    d = np.hypot(valid.x_px[:, None] - truth[:, 0], valid.y_px[:, None] - truth[:, 1])
    # a marker is found when a valid blob lies within half its radius (round units) of it
    nearest = np.argmin(d, axis=0)
    found = d[nearest, np.arange(len(truth))] < 0.5 * radius
    unique = np.unique(nearest[found]).size == found.sum()
    return found.mean(), unique, len(valid)


@pytest.mark.parametrize(
    ("angle_deg", "recall_min"),
    [
        ((0.0, 0.0), 0.98),
        ((90.0, 90.0), 0.98),
        ((25.0, 65.0), 0.98),
        ((-65.0, -25.0), 0.98),
        ((-90.0, 90.0), 0.95),
    ],
    ids=["side_by_side", "one_above_the_other", "ul", "ur", "any_direction"],
)
def test_pairs_one_radius_apart_are_split(rng, angle_deg, recall_min):
    truth, radius = _pairs(rng, angle_deg)
    blobs = detect_blobs(render(truth, radius), KISS)
    recall, unique, n_valid = _recall(blobs, truth, radius)
    assert recall >= recall_min
    assert unique or recall_min < 0.98
    # never more valid blobs than markers: splitting does not invent markers
    assert n_valid <= len(truth)


def test_splitting_off_keeps_pairs_merged(rng):
    truth, radius = _pairs(rng, (0.0, 0.0))

    params = KISS.replace(split_long_wide=False, split_touching=False)
    blobs = detect_blobs(render(truth, radius), params)
    assert len(blobs) == len(truth) - 30


@pytest.mark.parametrize("blur_px", [0.0, 0.3, 0.6, 0.8])
def test_single_markers_are_never_split_whatever_the_blur(rng, blur_px):
    gx, gy = np.meshgrid(np.linspace(40, 700, 12), np.linspace(30, 260, 7))
    truth = np.column_stack([gx.ravel(), gy.ravel()]) + rng.uniform(-3, 3, (84, 2))
    blobs = detect_blobs(render(truth, rng.uniform(1.8, 5.0, 84), blur_px=blur_px), KISS)
    assert len(blobs) == 84
    assert not blobs.flags.any()
