"""Markers touching an LED ring are separated from it (beyond Shafiq et al. 2001)."""

from __future__ import annotations

import numpy as np

from kisscal.detect import blobs as fl
from kisscal.detect import detect_blobs
from tests.detect.conftest import KISS, render


def _scene(gap_px: float) -> tuple[np.ndarray, np.ndarray]:
    led = np.array([[200.0, 100.0]])
    marker = np.array([[200.0 + 9.0 + 3.0 + gap_px, 102.0]])
    image = np.maximum(
        render(led, 9.0, peak=255.0),
        render(marker, 3.0),
    )
    return image, marker[0]


def test_touching_marker_is_detached_and_led_stays_invalid():
    image, marker = _scene(gap_px=-1.0)
    blobs = detect_blobs(image, KISS)
    assert np.count_nonzero(~blobs.valid) == 1
    assert blobs.flags[~blobs.valid][0] & fl.TOO_LARGE
    valid = blobs.valid_only()
    assert len(valid) == 1
    assert valid.flags[0] & fl.DETACHED
    assert np.hypot(valid.x_px[0] - marker[0], valid.y_px[0] - marker[1]) < 1.0
    # Shafiq et al. 2001 alone: the marker is lost in the invalid LED group
    without = detect_blobs(image, KISS.replace(detach_from_large=False))
    assert not without.valid.any()


def test_led_ring_alone_gives_no_pieces():
    image = render(np.array([[200.0, 100.0], [500.3, 150.6]]), 9.0, peak=255.0)
    blobs = detect_blobs(image, KISS)
    assert len(blobs) == 2
    assert not blobs.valid.any()
    assert not (blobs.flags & fl.DETACHED).any()
