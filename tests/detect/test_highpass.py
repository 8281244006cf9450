"""The band-pass centroid keeps a dot's centre on its bright core when a dim reflected
ghost crescent or halo is joined to it (real calibration images through glass and water),
and stays unbiased on clean round spots. Truth: rendered spots with known centres."""

from __future__ import annotations

import numpy as np

from kisscal.detect import DetectionParams, detect_blobs
from kisscal.detect.configure import configure_detection
from tests.detect.conftest import render

SIZE = (400, 300)


def _field(ghost: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Dots (radius 5 px) on an uneven, noisy background, each with a dim disc of
    contrast ``ghost`` 4 px to its left (a reflection); and the dots' true centres."""
    rng = np.random.default_rng(seed)
    gx, gy = np.meshgrid(np.arange(6), np.arange(4))
    centres = np.column_stack([50 + 60 * gx.ravel(), 50 + 65 * gy.ravel()]).astype(float)
    centres += rng.uniform(-0.5, 0.5, centres.shape)
    dots = render(centres, 5.0, size_px=SIZE, peak=200.0, blur_px=1.0, background=0.0, aspect=1.0)
    image = dots.astype(float)
    if ghost:
        shifted = centres - [4.0, 0.0]
        image = np.maximum(
            image,
            render(shifted, 6.0, size_px=SIZE, peak=ghost, blur_px=1.5, background=0, aspect=1),
        )
    yy, xx = np.mgrid[: SIZE[1], : SIZE[0]]
    image += 20 + 25 * np.sin(xx / 70.0) * np.cos(yy / 60.0) + rng.normal(0, 1.0, image.shape)
    return image.clip(0, 255).astype(np.uint8), centres


def _errors(image: np.ndarray, truth: np.ndarray, params: DetectionParams) -> np.ndarray:
    valid = detect_blobs(image, params).valid_only()
    d = np.hypot(*(truth[:, None, :] - valid.xy_px[None, :, :]).transpose(2, 0, 1))
    return d.min(axis=1)


def test_derived_on_uneven_backgrounds_and_off_on_even_ones() -> None:
    image, _ = _field(ghost=40.0)
    setup = configure_detection([image])
    assert setup.params.background_tile_px > 0
    side = setup.params.centroid_highpass_px
    assert side % 2 == 1 and 9 <= side <= 17, setup.choices["centroid_highpass_px"].why
    even = render(_field(0.0)[1], 5.0, size_px=SIZE, aspect=1.0, noise_sigma=1.0)
    assert configure_detection([even]).params.centroid_highpass_px == 0


def test_a_ghost_crescent_moves_the_band_pass_centroid_far_less() -> None:
    image, truth = _field(ghost=45.0, seed=1)
    params = configure_detection([image]).params
    assert params.centroid_highpass_px > 0
    band = _errors(image, truth, params)
    plain = _errors(image, truth, params.replace(centroid_highpass_px=0))
    assert np.median(plain) > 0.5, plain  # the ghost drags the plain centroid
    assert np.median(band) < 0.5 * np.median(plain), (band, plain)


def test_clean_round_spots_stay_unbiased() -> None:
    image, truth = _field(ghost=0.0, seed=2)
    params = configure_detection([image]).params
    assert params.centroid_highpass_px > 0
    assert np.all(_errors(image, truth, params) < 0.1)
