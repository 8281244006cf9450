"""Threshold on a noise-free (clipped) background (kisscal.detect.clipped), against truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from kisscal.detect import DetectionParams, detect_blobs
from kisscal.detect.clipped import crowd_notes, noise_free
from kisscal.detect.configure import configure_detection


def _clipped_target(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A calibration target's saturated dots over a background clipped to 0, with a few
    hundred faint specks (dust, stray light: a few grey levels, a few pixels), and the
    dots' true centres."""
    h, w = 480, 640
    gx, gy = np.meshgrid(np.arange(60, w - 40, 70.0), np.arange(60, h - 40, 70.0))
    dots = np.column_stack([gx.ravel(), gy.ravel()]) + rng.uniform(-0.5, 0.5, (gx.size, 2))
    specks = rng.uniform(5, [w - 5, h - 5], (400, 2))
    yy, xx = np.mgrid[:h, :w]
    image = rng.normal(-4.0, 1.5, (h, w))  # the camera's offset puts the background below 0
    for (x, y), amp, sigma in [
        *((d, 600.0, 4.0) for d in dots),
        *((s, a, 1.0) for s, a in zip(specks, rng.uniform(6, 12, len(specks)), strict=True)),
    ]:
        r = int(4 * sigma)
        sl = (slice(max(int(y) - r, 0), int(y) + r + 1), slice(max(int(x) - r, 0), int(x) + r + 1))
        image[sl] += amp * np.exp(-((xx[sl] - x) ** 2 + (yy[sl] - y) ** 2) / (2 * sigma**2))
    return np.round(image).clip(0, 255).astype(np.uint8), dots


def test_clipped_background_threshold_comes_from_the_dots() -> None:
    image, dots = _clipped_target(np.random.default_rng(4))
    setup = configure_detection([image], kind="grid")
    assert noise_free(setup.levels)  # the clipped background has no measurable noise
    blobs = detect_blobs(image, setup.params).valid_only()
    xy = np.column_stack([blobs.x_px, blobs.y_px])
    dist, _ = cKDTree(xy).query(dots)
    assert np.all(dist < 0.5)  # every dot, where it is
    # the specks (up to 12 grey levels) stay below the threshold: few blobs besides the dots
    assert len(blobs) <= len(dots) + 10
    assert setup.params.threshold > 12


@pytest.mark.parametrize(("step", "warned"), [(3, True), (5, False)])
def test_a_crowd_of_groups_is_reported(step: int, warned: bool) -> None:
    # 2 x 2 specks every ``step`` pixels: 27 889 groups (a crowd) or 10 000 (dense particles)
    image = np.zeros((500, 500), np.uint8)
    for dy in (0, 1):
        for dx in (0, 1):
            image[dy::step, dx::step] = 100
    params = DetectionParams(threshold=50.0)
    if warned:
        with pytest.warns(UserWarning, match="groups per frame"):
            notes = crowd_notes([image], params)
        assert len(notes) == 1 and str(len(range(0, 500, step)) ** 2) in notes[0]
    else:
        assert crowd_notes([image], params) == ()
