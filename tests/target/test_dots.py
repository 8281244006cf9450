"""Dots of a photographed target, under uneven light, against their true positions."""

from __future__ import annotations

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
