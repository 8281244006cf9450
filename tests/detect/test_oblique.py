"""Dots of a target seen obliquely along a diagonal are found whole with default settings.

A plate tilted about a diagonal images its round dots as ellipses elongated along the
other diagonal; every dot alike. Their x and y spreads are equal, so the height-to-width
ratio reads them as round, but the overlap test (Shafiq et al. 2001, section 2.3.2, read
from moments) takes a spot elongated along a diagonal for two overlapped markers: on
calibration images of Ni's lab (tests/detect/openlpt_heldout.py, camera 5) the default
kind cut 91 of 133 dots in two. The check that turns the shape tests off reads both.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from kisscal.detect import detect_blobs
from kisscal.detect.configure import configure_detection

SPACING = 40.0


def _oblique_target(rng: np.random.Generator, angle_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Dark elliptical dots (semi-axes 7 and 4 px, major axis at ``angle_deg``) on a lit
    plate, 4 x 4 sub-pixel coverage, a little blur and noise; and their centres."""
    side = 8
    g = (np.arange(side) + 1.0) * SPACING
    centres = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    centres += rng.uniform(-0.5, 0.5, centres.shape)
    size = int((side + 1) * SPACING)
    sub = (np.arange(4) + 0.5) / 4 - 0.5
    ys, xs = np.mgrid[0:size, 0:size].astype(float)
    xs = xs[..., None, None] + sub[None, None, None, :]
    ys = ys[..., None, None] + sub[None, None, :, None]
    cell = np.round((xs - SPACING) / SPACING).clip(0, side - 1).astype(int)
    row = np.round((ys - SPACING) / SPACING).clip(0, side - 1).astype(int)
    cx, cy = centres[row * side + cell, 0], centres[row * side + cell, 1]
    a = np.radians(angle_deg)
    u = (xs - cx) * np.cos(a) + (ys - cy) * np.sin(a)
    v = -(xs - cx) * np.sin(a) + (ys - cy) * np.cos(a)
    cover = ((u / 7.0) ** 2 + (v / 4.0) ** 2 <= 1).mean(axis=(2, 3))
    image = 220.0 - 180.0 * cover + rng.normal(0, 2.0, cover.shape)
    return np.clip(image, 0, 255).astype(np.uint8), centres


def test_obliquely_seen_dots_are_not_cut_as_overlapped_pairs() -> None:
    # measured: 64 of 64 found within 0.5 px, none split; before the check read the
    # overlap test: 0 of 64, each cut in two
    rng = np.random.default_rng(23)
    for angle in (45.0, 135.0):
        image, dots = _oblique_target(rng, angle)
        setup = configure_detection([image])  # kisscal detect's default kind (markers)
        valid = detect_blobs(image, setup.params).valid_only()
        d, _ = cKDTree(valid.xy_px).query(dots)
        pieces = cKDTree(valid.xy_px).query_ball_point(dots, 0.3 * SPACING, return_length=True)
        assert (d <= 0.5).all(), (angle, int((d > 0.5).sum()))
        assert (np.asarray(pieces) == 1).all(), (angle, int((np.asarray(pieces) > 1).sum()))
