"""Whether single markers image as round spots (kisscal.detect.roundness), from moments."""

from __future__ import annotations

import numpy as np

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
