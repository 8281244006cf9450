"""Small rendered IR fields for the detection tests (independent of the synthetic rig)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from kisscal.detect import DetectionParams

ASPECT = 1.94  # width / height of a round marker in KISS field pixels

#: The KISS camera's detection settings, as a lab with 752 x 291 fields would give them in
#: [detection] (kisscal derives them from the images; these tests exercise the Shafiq tests
#: on KISS-like fields with the settings fixed).
KISS = DetectionParams(
    pixel_aspect=ASPECT,
    max_pixels=80,
    max_width_px=14,
    max_height_px=9,
    detach_kernel_px=(11, 7),
    centroid_margin_y_px=2,
)


def render(
    centres_px: NDArray[np.float64],
    radius_x_px: float | NDArray[np.float64],
    size_px: tuple[int, int] = (752, 291),
    peak: float = 230.0,
    blur_px: float = 0.6,
    background: float = 6.0,
    noise_sigma: float = 0.0,
    rng: np.random.Generator | None = None,
    aspect: float = ASPECT,
    glow: NDArray[np.float64] | None = None,
) -> NDArray[np.uint8]:
    """Anti-aliased elliptical spots (x radius ``radius_x_px``, y radius / ``aspect``),
    blurred, over a flat ``background`` (plus ``glow``, an image of extra background).

    Coverage is estimated on a 8 x 8 sub-pixel grid per pixel, so the spot's grey centroid
    is its centre up to quantisation.
    """
    w, h = size_px
    centres_px = np.atleast_2d(np.asarray(centres_px, dtype=float))
    rx = np.broadcast_to(np.asarray(radius_x_px, dtype=float), len(centres_px))
    sub = (np.arange(8) + 0.5) / 8 - 0.5
    image = np.zeros((h, w))
    for (cx, cy), r in zip(centres_px, rx, strict=True):
        ry = r / aspect
        x0, x1 = max(int(np.floor(cx - r - 1)), 0), min(int(np.ceil(cx + r + 1)), w - 1)
        y0, y1 = max(int(np.floor(cy - ry - 1)), 0), min(int(np.ceil(cy + ry + 1)), h - 1)
        xs = np.arange(x0, x1 + 1)[:, None] + sub[None, :]
        ys = np.arange(y0, y1 + 1)[:, None] + sub[None, :]
        inside = (
            ((xs[None, :, None, :] - cx) / r) ** 2 + ((ys[:, None, :, None] - cy) / ry) ** 2
        ) <= 1
        patch = image[y0 : y1 + 1, x0 : x1 + 1]
        np.maximum(patch, inside.mean(axis=(2, 3)) * peak, out=patch)
    if blur_px > 0:
        image = cv2.GaussianBlur(image, (0, 0), blur_px)
    image += background
    if glow is not None:
        image += glow
    if noise_sigma > 0:
        image += (rng or np.random.default_rng(0)).normal(0, noise_sigma, image.shape)
    return np.clip(np.rint(image), 0, 255).astype(np.uint8)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(7)
