"""Dark dots on a bright plate (printed targets in ordinary light) are found with defaults.

Truth: a synthetic plate of black dots, unevenly lit, with sensor noise (centroids known),
and a real calibration crop (fixtures/real/openptv-cavity, bright dots) inverted, whose
dots OpenPTV's calibration puts on its detections. Bright-marker images, synthetic and
real, must stay bright: the decision never turns on weak evidence.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kisscal.detect import DetectionParams, detect_blobs
from kisscal.detect.configure import configure_detection
from kisscal.detect.polarity import dark_spots, frames_polarity, invert
from kisscal.io.frames import read_image
from tests.detect.conftest import render
from tests.detect.real_acceptance import score_dots

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "real" / "openptv-cavity"


def _dark_plate(seed: int = 0, uneven: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Black dots (radius 6 px, 7 x 5 lattice) on a white plate lit unevenly (by 45 grey
    levels times ``uneven``), and their true centres."""
    rng = np.random.default_rng(seed)
    gx, gy = np.meshgrid(np.arange(7), np.arange(5))
    centres = np.column_stack([80 + 60 * gx.ravel(), 60 + 55 * gy.ravel()]).astype(float)
    centres += rng.uniform(-0.5, 0.5, centres.shape)
    dots = render(
        centres, 6.0, size_px=(520, 340), peak=170.0, blur_px=1.0, background=0.0, aspect=1.0
    ).astype(float)
    yy, xx = np.mgrid[:340, :520]
    plate = 235.0 + uneven * (30.0 * (xx / 520.0) - 15.0 * (yy / 340.0) - 35.0)
    image = plate - dots * (plate / 230.0) + rng.normal(0, 2.0, plate.shape)
    return image.clip(0, 255).astype(np.uint8), centres


def _found(blobs, truth: np.ndarray) -> np.ndarray:
    """Distance from each true centre to the nearest valid blob (inf without one)."""
    valid = blobs.valid_only()
    if len(valid) == 0:
        return np.full(len(truth), np.inf)
    d = np.hypot(*(truth[:, None, :] - valid.xy_px[None, :, :]).transpose(2, 0, 1)).min(1)
    return d


def test_dark_dots_on_a_bright_plate_are_found_with_derived_settings() -> None:
    image, truth = _dark_plate()
    setup = configure_detection([image])
    assert setup.params.polarity == "dark", setup.choices["polarity"].why
    assert setup.choices["polarity"].source == "derived"
    assert "dark spots" in setup.summary()
    blobs = detect_blobs(image, setup.params)
    d = _found(blobs, truth)
    assert np.all(d < 0.25), d.max()
    assert len(blobs.valid_only()) == len(truth)


def test_dark_dots_are_found_by_the_default_parameters() -> None:
    """``detect_blobs`` with no settings decides per image ("auto"); evenly lit, as the
    default threshold (an absolute grey level) needs."""
    image, truth = _dark_plate(1, uneven=0.0)
    assert DetectionParams().polarity == "auto"
    d = _found(detect_blobs(image), truth)
    assert np.all(d < 0.5), d.max()
    # told "bright", the plate is one bright region and no dot is found
    bright = detect_blobs(image, DetectionParams(polarity="bright"))
    assert not np.any(_found(bright, truth) < 1.0)


@pytest.mark.parametrize("name", ["cal1", "cal4"])
def test_a_real_target_inverted_is_found_as_well_as_the_original(name: str) -> None:
    """Real glare, specks and uneven light, turned into dark dots on a bright plate."""
    image = read_image(FIXTURES / f"{name}.png")
    dots = np.loadtxt(FIXTURES / f"{name}_dots.csv", delimiter=",", skiprows=1, ndmin=2)
    negative = invert(image)
    setup = configure_detection([negative])
    assert setup.params.polarity == "dark", setup.choices["polarity"].why
    inverted = score_dots(detect_blobs(negative, setup.params), dots, dots)
    original = score_dots(detect_blobs(image, configure_detection([image]).params), dots, dots)
    assert inverted["found_1px"] >= 0.95 * len(dots), inverted
    assert inverted["split"] == 0, inverted
    assert inverted["found_1px"] == original["found_1px"], (inverted, original)


@pytest.mark.parametrize("name", ["cal1", "cal4", "particles1", "target_cam1_crop"])
def test_real_bright_spot_frames_stay_bright(name: str) -> None:
    image = read_image(FIXTURES / f"{name}.png")
    dark, why = dark_spots(image)
    assert not dark, why
    assert configure_detection([image]).params.polarity == "bright"


def test_bright_markers_stay_bright_and_a_dark_wall_object_is_no_target() -> None:
    rng = np.random.default_rng(3)
    markers = render(
        rng.uniform(20, [500, 270], (30, 2)),
        3.0,
        size_px=(520, 290),
        aspect=1.0,
        noise_sigma=1.0,
        rng=rng,
    )
    assert not dark_spots(markers)[0]
    # a bright wall with one large dark object (a door, a person) and no dots
    wall = np.full((300, 400), 210, np.uint8)
    wall[50:250, 100:220] = 20
    dark, why = dark_spots(wall)
    assert not dark and "compact dark spots" in why


def test_given_polarity_is_kept_and_16_bit_and_boolean_images_invert() -> None:
    image, truth = _dark_plate(2, uneven=0.0)
    assert frames_polarity([image], "bright")[0] == "bright"
    setup = configure_detection([image], {"polarity": "dark"})
    assert setup.choices["polarity"].source == "given"
    wide = image.astype(np.uint16) * 257  # the same plate from a 16-bit camera
    assert np.all(_found(detect_blobs(wide), truth) < 0.5)
    white_plate = image > 100  # thresholded the other way round: the dots are unset
    blobs = detect_blobs(white_plate)
    assert np.all(_found(blobs, truth) < 0.5)
