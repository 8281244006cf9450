"""Dots of a photographed target, under uneven light, against their true positions."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from kisscal.synth.target import render_target, target_points, target_rig
from kisscal.target.dots import find_dots, find_target_dots


@pytest.mark.parametrize("kind", ["planar", "stepped"])
def test_every_dot_found_to_a_fraction_of_a_pixel(kind: str) -> None:
    xyz, surfaces = target_points(kind)
    for seed in (1, 2):
        cam = target_rig(seed)[1]
        image = render_target(cam, xyz, surfaces, np.random.default_rng(seed))
        dots = find_dots(image, "dark")
        truth = cam.project(xyz)
        d = np.linalg.norm(truth[:, None] - dots[None], axis=2)
        err = d.min(axis=1)  # every dot found; those by a plate's edge are the worst
        assert err.max() < 0.2 and np.sqrt(np.mean(err**2)) < 0.06
        assert (d.min(axis=0) > 2).sum() <= 8  # besides: a few corners of the plates


def test_polarity_follows_the_seeds() -> None:
    xyz, surfaces = target_points("planar")
    cam = target_rig(3)[0]
    image = render_target(cam, xyz, surfaces, np.random.default_rng(0))
    seeds = cam.project(xyz[:6])
    dark = find_target_dots(image, seeds)
    bright = find_target_dots(255 - image, seeds)
    assert len(dark) >= len(xyz) and np.allclose(np.sort(dark, axis=0), np.sort(bright, axis=0))


def test_polarity_follows_rough_clicks_on_large_dots_among_specks() -> None:
    """Bright dots 22 x 12 px on a dark tank among bright specks, clicked 4-6 px off their
    centres (as OpenPTV's users clicked github OpenPTV/example_2cam_90deg): the bright dots.
    A count of dots within 3 px of the clicks found none of either polarity and took the
    dark ones, and the target route then matched nothing."""
    rng = np.random.default_rng(5)
    image = np.full((400, 500), 12, np.uint8)
    centres = np.array([(60.0 + 60 * i, 50.0 + 50 * j) for i in range(7) for j in range(7)])
    for u, v in centres:
        cv2.ellipse(image, (int(u), int(v)), (11, 6), 0, 0, 360, 200, -1)
    specks = rng.integers((0, 0), (500, 400), (400, 2))
    image[specks[:, 1], specks[:, 0]] = 160
    image = cv2.GaussianBlur(image, (0, 0), 1.0)
    angle = rng.uniform(0, 2 * np.pi, 4)
    clicks = (
        centres[[0, 6, 42, 48]]
        + rng.uniform(4, 6, 4)[:, None] * np.c_[np.cos(angle), np.sin(angle)]
    )
    dots = find_target_dots(image, clicks)
    d = np.linalg.norm(centres[:, None] - dots[None], axis=2).min(axis=1)
    assert (d < 1.0).all(), d.max()
    assert np.array_equal(dots, find_dots(image, "bright"))
