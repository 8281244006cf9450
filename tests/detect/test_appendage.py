"""Thin appendages cut off thick spots (kisscal.detect.appendage): a dot touching a streak."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.detect import DetectionParams, detect_blobs
from kisscal.detect import blobs as fl

SIZE = dict(max_pixels=400, max_width_px=24, max_height_px=24, min_pixels=3)


def _scene(streak: bool, x: float = 60.3, y: float = 40.6, dot_radius: float = 6.0) -> np.ndarray:
    """A flat dot (radius 6 px, soft edge) with a thin dim streak leaving it diagonally."""
    rng = np.random.default_rng(5)
    image = rng.normal(20.0, 1.0, (90, 130))
    yy, xx = np.mgrid[: image.shape[0], : image.shape[1]]
    r = np.hypot(xx - x, yy - y)
    image += 180.0 * np.clip(dot_radius + 0.5 - r, 0.0, 1.0)
    if streak:  # 2 px wide, 30 px long, up and to the left of the dot
        t = np.linspace(0.0, 30.0, 400)
        sx = np.rint(x - dot_radius * 0.7 - t * 0.6).astype(int)
        sy = np.rint(y - dot_radius * 0.7 - t * 0.8).astype(int)
        for dx in (0, 1):
            image[sy, sx + dx] = 20.0 + 70.0
    return image.clip(0, 255).astype(np.uint8)


@pytest.mark.parametrize("streak", [False, True])
def test_dot_with_a_streak_is_found_at_its_centre(streak):
    blobs = detect_blobs(_scene(streak), DetectionParams(threshold=40.0, **SIZE)).valid_only()
    d = np.hypot(blobs.x_px - 60.3, blobs.y_px - 40.6)
    assert d.min() < 0.15
    dot = int(np.argmin(d))
    # the dot holds its own pixels only (a disc of radius 6: about 113 px)
    assert 100 <= blobs.pixels[dot] <= 135
    if streak:
        assert blobs.flags[dot] & fl.DETACHED
        # the streak is left in blobs of its own (the shape tests may cut it), none
        # of them a piece of the dot
        others = np.delete(d, dot)
        assert others.size >= 1 and others.min() > 8.0


def test_without_the_cut_the_streak_drags_the_dot():
    """The failure the cut prevents: the same scene with the step off."""
    params = DetectionParams(threshold=40.0, detach_appendages=False, **SIZE)
    blobs = detect_blobs(_scene(True), params).valid_only()
    assert np.hypot(blobs.x_px - 60.3, blobs.y_px - 40.6).min() > 0.5


def test_round_dots_and_thin_lines_alone_are_left_whole():
    image = _scene(False)
    image[70:72, 10:50] = 90  # a streak touching nothing
    blobs = detect_blobs(image, DetectionParams(threshold=40.0, **SIZE))
    assert not (blobs.flags & fl.DETACHED).any()
    assert len(blobs) == 2
