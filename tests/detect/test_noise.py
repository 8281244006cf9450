"""Noise removal (Shafiq et al. 2001, section 2.2)."""

from __future__ import annotations

import numpy as np

from kisscal.detect import detect_blobs
from tests.detect.conftest import KISS, render


def test_lonely_pixels_and_streaks_are_removed():
    image = render(np.array([[100.0, 100.0]]), 2.5)
    image[20, 300] = 200  # lonely pixel
    image[50, 400:425] = 180  # one-pixel-high streak
    image[200:209, 600] = 220  # one-pixel-wide streak
    blobs = detect_blobs(image, KISS)
    assert len(blobs) == 1
    assert abs(blobs.x_px[0] - 100) < 0.1


def test_switching_the_rules_off_keeps_them():
    image = np.zeros((40, 60), dtype=np.uint8)
    image[5, 5] = 255
    image[10, 10:30] = 255
    image[20:30, 50] = 255
    off = KISS.replace(
        remove_lonely=False,
        remove_one_pixel_wide=False,
        remove_one_pixel_high=False,
        noise_min_width_px=0,
        noise_min_height_px=0,
    ).without_advanced_analysis()
    assert len(detect_blobs(image, off)) == 3
    assert len(detect_blobs(image, KISS)) == 0


def test_smallest_far_marker_survives():
    # A 25 mm sphere at ~7 m images about 4.5 x 2.3 px: still two or more lines high at the
    # default threshold, so the one-pixel-high rule does not remove it.
    rng = np.random.default_rng(3)
    centres = np.column_stack([rng.uniform(20, 730, 40), rng.uniform(10, 280, 40)])
    centres = centres[np.argsort(centres[:, 0])]
    centres[:, 0] = np.linspace(20, 730, 40)
    image = render(centres, 1.8)
    blobs = detect_blobs(image, KISS)
    assert len(blobs) == 40
    assert blobs.valid.all()
