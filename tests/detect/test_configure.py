"""Detection settings derived from the images (kisscal.detect.configure), against truth."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.detect import detect_blobs
from kisscal.detect.aspect import measure_pixel_aspect
from kisscal.detect.configure import configure_detection
from kisscal.detect.pipeline import threshold_image
from kisscal.detect.survey import survey_frames
from kisscal.errors import KisscalError
from tests.detect.conftest import render

SIZE = (640, 480)
EDGE_X = 450  # where the glow test's bright surround begins


def _scene(rng: np.random.Generator, n: int, radius: tuple[float, float], keep_off=()):
    """``n`` marker centres at least 6 radii apart (and clear of ``keep_off`` discs), and
    their x radii."""
    w, h = SIZE
    pts: list[np.ndarray] = []
    while len(pts) < n:
        p = rng.uniform([30, 30], [w - 30, h - 30])
        clear = all(np.hypot(*(p - c)) > r + 3 * radius[1] for c, r in keep_off)
        clear &= abs(p[0] - EDGE_X) > 20  # off the edge of the bright surround
        if clear and all(np.hypot(*(p - q)) > 6 * radius[1] for q in pts):
            pts.append(p)
    return np.array(pts), rng.uniform(*radius, n)


def _frames(rng, aspect=1.0, k=8, noise=1.5, glow=None, leds=()):
    """``k`` frames of 30 moving markers (and fixed LED rings) with their truth."""
    frames, truth = [], []
    for _ in range(k):
        centres, radii = _scene(rng, 30, (2.0, 5.0), leds)
        if leds:
            centres = np.vstack([centres, [c for c, _ in leds]])
            radii = np.concatenate([radii, [r for _, r in leds]])
        image = render(centres, radii, SIZE, noise_sigma=noise, rng=rng, aspect=aspect, glow=glow)
        frames.append(image)
        truth.append((centres[:30], radii[:30]))
    return frames, truth


def _recall_rms(frames, truth, params) -> tuple[float, float]:
    found, errors = 0, []
    total = 0
    for image, (centres, _radii) in zip(frames, truth, strict=True):
        blobs = detect_blobs(image, params).valid_only()
        d = np.hypot(blobs.x_px[:, None] - centres[:, 0], blobs.y_px[:, None] - centres[:, 1])
        best = d.min(axis=0)
        found += int((best < 0.5).sum())
        errors += best[best < 0.5].tolist()
        total += len(centres)
        assert len(blobs) == len(centres)  # no extra valid blob
    return found / total, float(np.sqrt(np.mean(np.square(errors))))


def test_square_pixels_and_led_rings(rng) -> None:
    leds = ((np.array([100.0, 100.0]), 14.0), (np.array([500.0, 380.0]), 16.0))
    frames, truth = _frames(rng, leds=leds)
    setup = configure_detection(frames)
    p = setup.params
    assert p.pixel_aspect == 1.0
    assert setup.levels.background == pytest.approx(6.0, abs=1)
    # every true marker inside the size band, the LED rings above it
    areas = np.concatenate([np.pi * r**2 for _, r in truth])
    assert p.max_pixels >= areas.max() and p.max_pixels < np.pi * 14.0**2
    recall, rms = _recall_rms(frames, truth, p)
    assert recall == 1.0 and rms < 0.05
    image = frames[0]
    flagged = detect_blobs(image, p).select(~detect_blobs(image, p).valid)
    assert len(flagged) == 2  # both LED rings, too large


@pytest.mark.parametrize("aspect", [1.94, 0.75])
def test_pixel_aspect_of_non_square_pixels(rng, aspect) -> None:
    # From marker shapes alone the aspect is known to about 15 % (blur and blooming widen
    # small spots alike in x and y); a session takes it from the grid lattice instead
    # (kisscal.grid.lattice.lattice_pixel_aspect, exact to a fraction of a percent).
    frames, _ = _frames(rng, aspect=aspect, k=10, noise=0.5)
    measured, why = measure_pixel_aspect(survey_frames(frames, 20.0, 40))
    assert measured == pytest.approx(aspect, rel=0.15), why
    square, _ = _frames(rng, aspect=1.0, k=10, noise=0.5)
    assert measure_pixel_aspect(survey_frames(square, 20.0, 40))[0] == 1.0


def test_a_survey_without_shapes_skips_only_the_moments(rng) -> None:
    # the first survey of the derivation reads sizes and contrast, never shapes
    frames, _ = _frames(rng, k=3, noise=0.5)
    full, quick = survey_frames(frames, 20.0, 40), survey_frames(frames, 20.0, 40, shapes=False)
    assert len(full) > 20 and np.isfinite(full.var_x).all()
    for name in ("var_x", "var_y", "cov_xy"):
        assert np.isnan(getattr(quick, name)).all()
    for name in ("frame", "x", "y", "pixels", "width", "height", "peak", "fill", "isolation"):
        np.testing.assert_array_equal(getattr(quick, name), getattr(full, name))


def test_uneven_glow_gets_a_local_background(rng) -> None:
    # Markers right on the edge of a bright region (within a tile of it) are biased by
    # the background's change under them; they are kept 20 px off it here.
    yy, xx = np.mgrid[0 : SIZE[1], 0 : SIZE[0]]
    glow = 120.0 * np.exp(-(((xx - 200) / 180.0) ** 2 + ((yy - 150) / 140.0) ** 2))
    glow += 60.0 / (1.0 + np.exp(-(xx - EDGE_X) / 3.0))  # a bright surround, its edge blurred
    frames, truth = _frames(rng, glow=glow, noise=2.0)
    setup = configure_detection(frames)
    assert setup.params.background_tile_px > 0
    recall, rms = _recall_rms(frames, truth, setup.params)
    assert recall == 1.0 and rms < 0.05
    # one grey level for the whole image would swallow the glow as one huge blob
    plain = setup.params.replace(background_tile_px=0, threshold=setup.params.threshold + 6)
    assert detect_blobs(frames[0], plain).pixels.max() > 10_000


@pytest.mark.parametrize("bits", [8, 10, 12])
def test_narrow_data_in_16_bit_containers(rng, bits: int) -> None:
    """A 10-bit camera stored unshifted in 16-bit PNGs tops out at 1023, 1/64 of the
    container: every fixed floor of the derivation (a few grey levels) must shrink with it
    (a modern-preset seed found no grid dot at all before)."""
    frames, truth = _frames(rng, noise=1.0)
    wide = [f.astype(np.uint16) * 2 ** (bits - 8) for f in frames]  # 0 .. 2^bits - 1
    setup = configure_detection(wide)
    assert setup.levels.bits == bits
    recall, rms = _recall_rms(wide, truth, setup.params)
    assert recall == 1.0 and rms < 0.05


def test_given_values_win_and_are_marked(rng) -> None:
    frames, _ = _frames(rng, k=5)
    setup = configure_detection(frames, {"threshold": 90.0, "pixel_aspect": 1.2})
    assert setup.params.threshold == 90.0 and setup.params.pixel_aspect == 1.2
    assert setup.choices["threshold"].source == "given"
    assert setup.choices["max_pixels"].source == "derived"
    assert "given: threshold, pixel_aspect" in setup.summary()
    with pytest.raises(KisscalError, match="did you mean 'threshold'"):
        configure_detection(frames, {"treshold": 3})


def test_dark_frames_and_binary_frames() -> None:
    dark = [np.full((100, 120), 4, np.uint8)] * 3
    setup = configure_detection(dark)
    assert setup.notes and "no bright spot" in setup.notes[0]
    assert len(detect_blobs(dark[0], setup.params)) == 0
    binary = [np.zeros((50, 60), bool)]
    assert configure_detection(binary).params.threshold == 40.0
    with pytest.raises(KisscalError, match="no images"):
        configure_detection([])


@pytest.mark.parametrize("shape", [(1024, 1280), (1023, 1279), (211, 197)])
@pytest.mark.parametrize("tile", [16, 24, 52])
def test_local_background_of_any_image_and_tile_size(shape, tile) -> None:
    """The sparse sample of the local background fits every image height and tile (a
    sample on the last line has no line below it), and the map follows a glow."""
    from kisscal.detect.background import local_background

    h, w = shape
    glow = np.tile(np.linspace(10.0, 90.0, w), (h, 1))
    noise = np.random.default_rng(1).normal(0.0, 1.0, shape)
    local = local_background((glow + noise).clip(0, 255).astype(np.uint8), tile)
    assert local.level.shape == shape
    inner = (slice(tile, h - tile), slice(tile, w - tile))  # the edges are extrapolated
    assert np.abs(local.level[inner] - glow[inner]).max() < 3.0
    assert 0.5 < float(np.median(local.noise)) < 1.6


def test_background_lit_at_the_markers_scale_gets_finer_tiles(rng) -> None:
    # lit walls of a real scene: bands about two marker diameters wide, bright above the
    # threshold; tiles of four marker diameters leave them white, finer tiles follow them
    # (three frames: a calibration image or a short sample, nothing called stationary)
    xx = np.arange(SIZE[0])
    walls = (100, 260, 380, 560)
    glow = np.zeros((SIZE[1], SIZE[0]))
    for x in walls:
        glow += 120.0 * np.exp(-0.5 * ((xx - x) / 5.0) ** 2)[None, :]
    frames, truth = [], []
    for _ in range(3):
        keep_off = [((x, y), 12.0) for x in walls for y in range(0, SIZE[1], 8)]
        centres, radii = _scene(rng, 20, (2.0, 5.0), keep_off)
        frames.append(render(centres, radii, SIZE, noise_sigma=1.5, rng=rng, aspect=1.0, glow=glow))
        truth.append((centres, radii))
    setup = configure_detection(frames)
    tile = setup.params.background_tile_px
    assert 0 < tile <= 24, setup.choices["background_tile_px"]
    # four marker diameters (the tile a smooth glow gets) leave about twice the walls white
    coarse = setup.params.replace(background_tile_px=2 * tile)
    white = [np.mean(threshold_image(frames[0], p)[0]) for p in (setup.params, coarse)]
    assert white[0] < 0.6 * white[1]
    assert _recall_rms(frames, truth, setup.params)[0] == 1.0


def test_the_printed_band_is_the_one_the_limits_keep(rng) -> None:
    # Moving glare joins the moving marker population (multiplane_example_2's particle
    # frames: "markers 2-3805 px, oversize above 304 px"): the band printed must not
    # reach past the upper limit that flags it too large.
    yy, xx = np.mgrid[:400, :600]
    spots = rng.uniform([20, 20], [580, 380], (80, 2))
    fixed = [(30, 30), (570, 30), (30, 370), (570, 370), (300, 20)]
    frames = []
    for f in range(6):
        image = rng.normal(10, 1, xx.shape)
        for x, y in np.vstack([spots + rng.uniform(-15, 15, spots.shape), fixed]):
            image += 200 * np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / 8.0)
        image[(xx - 150 - 40 * f) ** 2 + (yy - 200) ** 2 <= 25**2] = 250  # a moving glare
        frames.append(image.clip(0, 255).astype(np.uint8))
    setup = configure_detection(frames)
    low, high = setup.marker_pixels
    assert 0 < low < high <= setup.params.max_pixels < 1900
    assert f"markers {low}-{high} px, oversize above {setup.params.max_pixels} px" in (
        setup.summary()
    )
