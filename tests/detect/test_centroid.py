"""Weighted sub-pixel centroids (DESIGN.md convention) against rendered truth."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.detect import detect_blobs
from kisscal.detect.background import background_level as estimate_background
from tests.detect.conftest import KISS, render


def _scattered(rng: np.random.Generator, n: int) -> np.ndarray:
    # a jittered 10 x 8 lattice keeps the spots isolated
    gx, gy = np.meshgrid(np.linspace(30, 720, 10), np.linspace(20, 270, 8))
    lattice = np.column_stack([gx.ravel(), gy.ravel()])[:n]
    return lattice + rng.uniform(-4, 4, lattice.shape)


def _errors(blobs, truth):
    d = np.hypot(blobs.x_px[:, None] - truth[:, 0], blobs.y_px[:, None] - truth[:, 1])
    db = np.hypot(
        blobs.x_binary_px[:, None] - truth[:, 0], blobs.y_binary_px[:, None] - truth[:, 1]
    )
    i = np.argmin(d, axis=0)
    return d[i, np.arange(len(truth))], db[i, np.arange(len(truth))]


@pytest.mark.parametrize(("blur", "noise"), [(0.6, 0.0), (0.0, 0.0), (0.6, 1.0)])
def test_weighted_centroid_rms_below_five_hundredths(rng, blur, noise):
    truth = _scattered(rng, 80)
    radius = rng.uniform(2.0, 5.0, len(truth))
    image = render(truth, radius, blur_px=blur, noise_sigma=noise, rng=rng)
    blobs = detect_blobs(image, KISS)
    assert len(blobs) == len(truth)
    weighted, binary = _errors(blobs, truth)
    rms = np.sqrt(np.mean(weighted**2))
    assert rms <= 0.05
    # the binary centroid of equation (2) is far coarser: that is why the rim is weighted
    assert np.sqrt(np.mean(binary**2)) > 2 * rms


def test_binary_centroid_when_switched_off(rng):
    truth = _scattered(rng, 20)
    blobs = detect_blobs(render(truth, 3.0), KISS.replace(weighted_centroid=False))
    assert np.array_equal(blobs.x_px, blobs.x_binary_px)


def test_background_estimate_ignores_spots(rng):
    truth = _scattered(rng, 80)
    image = render(truth, 5.0, background=11.0, noise_sigma=1.0, rng=rng)
    assert abs(estimate_background(image) - 11.0) <= 1.0


def test_nearby_noise_pixel_does_not_pull_the_centroid():
    image = render(np.array([[200.3, 100.6]]), 3.0)
    clean = detect_blobs(image, KISS)
    image[100, 206] = 250  # bright pixel just outside the spot, inside its window
    noisy = detect_blobs(image, KISS)
    assert len(noisy) == 1
    assert abs(noisy.x_px[0] - clean.x_px[0]) < 0.01
