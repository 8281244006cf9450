"""A busy infrared frame for benchmarks: a bright, uneven surround and about a thousand dots.

The frame is the hard case of issue 11 (a dot target under a bright, uneven surround, as
in real calibration images): a large bright plate whose brightness varies across it and
whose light spills beyond its edges, a glowing lamp that saturates, a ramp across the
whole image, sensor noise, and ``n_dots`` round dots spread over everything (on the
plate, on the ramp, beside the lamp). At a threshold made for a dark background the plate
is one blob of hundreds of thousands of pixels; the dots' true centres come with it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.synth.render import RenderParams, Spots, record, render_scene


def _surround(size_px: tuple[int, int], rng: np.random.Generator) -> NDArray[np.float64]:
    """Background light (8-bit scale): ramp, a bright uneven plate, a saturating lamp."""
    w, h = size_px
    y, x = np.mgrid[0:h, 0:w].astype(float)
    light = 15.0 + 45.0 * (x / w) * rng.uniform(0.6, 1.0) + 15.0 * (y / h)
    # the plate: a soft-edged rectangle over about a third of the image, 70-150 grey levels
    x0, y0 = rng.uniform(0.08, 0.2) * w, rng.uniform(0.1, 0.25) * h
    x1, y1 = x0 + rng.uniform(0.45, 0.6) * w, y0 + rng.uniform(0.5, 0.65) * h
    edge = 0.015 * w
    inside = (
        np.clip((x - x0) / edge, 0, 1)
        * np.clip((x1 - x) / edge, 0, 1)
        * np.clip((y - y0) / edge, 0, 1)
        * np.clip((y1 - y) / edge, 0, 1)
    )
    shade = 70.0 + 80.0 * ((x - x0) / (x1 - x0)) * ((y - y0) / (y1 - y0))
    light += inside * np.clip(shade, 70.0, 150.0)
    # the lamp: a glow whose core saturates
    u, v, r = rng.uniform(0.7, 0.9) * w, rng.uniform(0.1, 0.3) * h, 0.05 * w
    light += 400.0 * np.exp(-((x - u) ** 2 + (y - v) ** 2) / (2 * r**2))
    return light


def busy_frame(
    seed: int, size_px: tuple[int, int] = (1280, 1024), n_dots: int = 1000
) -> tuple[NDArray[np.uint8], NDArray[np.float64]]:
    """A busy 8-bit frame and the true centres (px) of its ``n_dots`` dots.

    Dots are 5-12 px across and 110-180 grey levels above their local background, one
    per cell of a jittered lattice (so no two touch), never on the lamp's saturated core.
    Pure: the same seed gives the same frame.

    Examples
    --------
    >>> image, centres = busy_frame(1, (320, 256), n_dots=60)
    >>> image.shape, image.dtype, centres.shape
    ((256, 320), dtype('uint8'), (60, 2))
    """
    rng = np.random.default_rng([seed, 11011])
    w, h = size_px
    light = _surround(size_px, rng)
    cols = int(np.ceil(np.sqrt(1.3 * n_dots * w / h)))
    rows = int(np.ceil(1.3 * n_dots / cols))
    cell = np.array([w / cols, h / rows])
    r, c = np.divmod(np.arange(rows * cols), cols)
    centres = (np.column_stack([c, r]) + 0.5 + rng.uniform(-0.2, 0.2, (rows * cols, 2))) * cell
    radius = rng.uniform(2.5, 6.0, len(centres))
    iu, iv = np.clip(centres.astype(int), 0, [w - 1, h - 1]).T
    keep = (light[iv, iu] < 200) & np.all(centres - radius[:, None] - 3 >= 0, axis=1)
    keep &= (centres[:, 0] + radius + 3 < w) & (centres[:, 1] + radius + 3 < h)
    pick = rng.permutation(np.flatnonzero(keep))[:n_dots]
    if len(pick) < n_dots:
        raise ValueError(f"{size_px} px has room for {len(pick)} dots, not {n_dots}")
    pick = np.sort(pick)
    shape = radius[pick, None, None] * np.eye(2)
    spots = Spots(centres[pick], shape, rng.uniform(110.0, 180.0, len(pick)))
    params = RenderParams(
        background=0.0, noise_sigma=2.0, blur_px=0.8, noise_pixels=20.0, streak_probability=0.0
    )
    scene = render_scene(size_px, spots, params)
    return record(scene, rng, params, spots.centre_px, light), spots.centre_px
