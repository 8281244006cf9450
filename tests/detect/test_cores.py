"""Bright cores of oversized groups (kisscal.detect.cores): a dot touching a dim region."""

from __future__ import annotations

import numpy as np

from kisscal.detect import DetectionParams, detect_blobs
from kisscal.detect import blobs as fl

SIZE = dict(max_pixels=120, max_width_px=14, max_height_px=14, min_pixels=3)


def _dot(image: np.ndarray, x: float, y: float, peak: float, sigma: float) -> None:
    yy, xx = np.mgrid[: image.shape[0], : image.shape[1]]
    image += peak * np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / (2 * sigma**2))


def _scene(bar_level: float, dot_peak: float) -> np.ndarray:
    """A dim lit bar (60 x 8 px) with a blurred round dot touching its end."""
    rng = np.random.default_rng(3)
    image = rng.normal(20.0, 1.0, (80, 120))
    image[36:44, 20:80] += bar_level
    if dot_peak:
        _dot(image, 84.3, 39.6, dot_peak, 2.0)
    return image.clip(0, 255).astype(np.uint8)


def test_dot_touching_a_dim_bar_is_found_where_it_is():
    image = _scene(bar_level=40.0, dot_peak=200.0)
    params = DetectionParams(threshold=30.0, **SIZE)
    blobs = detect_blobs(image, params)
    d = np.hypot(blobs.x_px - 84.3, blobs.y_px - 39.6)
    best = int(np.argmin(d))
    assert blobs.valid[best] and d[best] < 0.5
    assert blobs.flags[best] & fl.DETACHED
    # the bar stays one oversized group, flagged as such
    assert ((blobs.flags & fl.TOO_LARGE) != 0).sum() == 1
    # without the core detach the dot is lost with the bar
    alone = detect_blobs(image, params.replace(detach_cores=False))
    near = np.hypot(alone.x_px - 84.3, alone.y_px - 39.6) < 1.0
    assert not (near & alone.valid).any()


def test_uniform_bright_region_keeps_no_core():
    image = _scene(bar_level=120.0, dot_peak=0.0)
    blobs = detect_blobs(image, DetectionParams(threshold=30.0, **SIZE))
    assert len(blobs.valid_only()) == 0
    assert not (blobs.flags & fl.DETACHED).any()
