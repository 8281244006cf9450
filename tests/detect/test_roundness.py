"""Whether single markers image as round spots (kisscal.detect.roundness), from moments."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

import kisscal.detect.blobs as fl
from kisscal.detect import detect_blobs
from kisscal.detect.configure import configure_detection
from kisscal.detect.params import DetectionParams
from kisscal.detect.roundness import aligned_ellipses, shapes_off_reason
from kisscal.detect.shape import PIXEL_AREA_VAR

PARAMS = DetectionParams(pixel_aspect=1.0, growth_px=0.0)


def _spots(major: np.ndarray, minor: np.ndarray, angle_deg: np.ndarray):
    """Raw moments (px^2) of spots of spreads ``major`` x ``minor`` px along ``angle_deg``."""
    a = np.radians(angle_deg)
    c, s = np.cos(a), np.sin(a)
    big, small = major**2, minor**2
    return (
        big * c * c + small * s * s + PIXEL_AREA_VAR,
        big * s * s + small * c * c + PIXEL_AREA_VAR,
        (big - small) * c * s,
    )


def test_a_tilted_plate_turns_the_tests_off_blur_and_pairs_do_not() -> None:
    rng = np.random.default_rng(5)
    n = 200
    sigma = rng.uniform(1.5, 3.0, n)
    round_ = (sigma, sigma * rng.uniform(0.95, 1.0, n), rng.uniform(0, 180, n))
    # a plate tilted about a diagonal: every dot 1.4 times longer along about 45 degrees
    plate = _spots(sigma * 1.4, sigma, 45 + rng.normal(0, 3, n))
    assert aligned_ellipses(*plate, PARAMS) > 0.95
    assert "one axis" in (shapes_off_reason(*plate, PARAMS) or "")
    # a walk: a tenth of the markers blurred along the way they move (one direction), the
    # rest round; and a twentieth touching pairs along a diagonal (twice as long)
    moving = rng.random(n) < 0.1
    pair = ~moving & (rng.random(n) < 0.05)
    major = np.where(moving, sigma * 2.0, np.where(pair, sigma * 2.0, round_[1]))
    angle = np.where(moving, 10.0, np.where(pair, 45.0, round_[2]))
    walk = _spots(major, round_[1], angle)
    assert aligned_ellipses(*walk, PARAMS) < 0.2
    # the long/wide test reads some of them (the blurred ones are wide): under 15 %
    assert shapes_off_reason(*walk, PARAMS) is None
    assert aligned_ellipses(*_spots(*round_), PARAMS) < 0.05


def _beads(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A plate of 70 beads lit from one side (as github OpenPTV/example_2cam_90deg's):
    a saturated glint at the top right of each, its body dim, its lower right unlit."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:480, :640].astype(float)
    image = rng.normal(2, 1, xx.shape)
    centres = np.array([(x, y) for y in range(50, 440, 56) for x in range(50, 600, 56)], float)
    centres += rng.uniform(-3, 3, centres.shape)
    for x0, y0 in centres:
        disc = np.clip((12.5 - np.hypot(xx - x0, yy - y0)) / 1.5, 0, 1)
        image += disc * np.where((xx - x0 > 1) & (yy - y0 > 1), 20.0, 75.0)
        image[((xx - x0 - 2) / 8) ** 2 + ((yy - y0 + 3) / 4.5) ** 2 <= 1] = 255
    return np.clip(image, 0, 255).astype(np.uint8), centres


def test_beads_with_a_glint_are_not_cut_by_the_shape_tests() -> None:
    # Their light is round (the survey's moments), their white pixels at the threshold are
    # not: a glint and a lit crescent, which the overlap test read as a pair (all 70 cut).
    image, centres = _beads()
    params = configure_detection([image], {"split_touching": False}).params
    blobs = detect_blobs(image, params)
    pieces = cKDTree(blobs.xy_px).query_ball_point(centres, 12.5, return_length=True)
    assert (np.asarray(pieces) == 1).all()
    assert blobs.valid.sum() == len(centres)
    assert not (blobs.flags & (fl.SPLIT_UL | fl.SPLIT_UR | fl.SPLIT_WIDE | fl.SPLIT_LONG)).any()
