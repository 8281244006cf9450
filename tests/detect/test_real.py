"""Detection with default settings on crops of real frames (fixtures/real/openptv-cavity).

The crops are cut from a real four-camera particle-tracking experiment (github
OpenPTV/test_cavity, MIT): calibration-target dots about 10 px wide on an uneven
background full of specks, and particle frames. The references are OpenPTV's own: the
dots its calibration puts on its detections, and its targets of the particle frame
(``make_crops.py`` beside the crops says how they were cut).
"""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest

from kisscal.detect import detect_blobs
from kisscal.detect.configure import configure_detection
from kisscal.detect.pipeline import hopeless
from kisscal.io.frames import read_image
from tests.detect.real_acceptance import score_dots, score_targets

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "real" / "openptv-cavity"
#: Most bytes of memory per image pixel that one detection may hold at its peak (the
#: former pixels x split-groups table took several thousand on a real frame).
BYTES_PER_PIXEL = 150


def _load(name: str) -> tuple[np.ndarray, np.ndarray]:
    image = read_image(FIXTURES / f"{name}.png")
    csv = next(FIXTURES.glob(f"{name}_*.csv"))
    return image, np.loadtxt(csv, delimiter=",", skiprows=1, ndmin=2)


@pytest.mark.parametrize("name", ["cal1", "cal4"])
def test_target_dots_found_whole_with_defaults(name: str) -> None:
    image, dots = _load(name)
    setup = configure_detection([image])
    # square pixels: dots about 10 px wide among specks are no evidence of anything else
    assert setup.params.pixel_aspect == 1.0, setup.choices["pixel_aspect"].why
    # the size band holds the dots (about 85-130 white pixels), not just the specks
    assert setup.params.max_pixels is not None and setup.params.max_pixels > 150
    score = score_dots(detect_blobs(image, setup.params), dots, dots)
    assert score["found_1px"] >= 0.95 * len(dots), score
    assert score["split"] == 0, score


def test_particles_found_with_defaults() -> None:
    # OpenPTV cuts touching particles at their grey-level peaks; kisscal keeps a pair
    # without a neck between them whole, so a few of its targets are missed (measured
    # 90 % of 143 on this crop)
    image, targets = _load("particles1")
    params = configure_detection([image]).params
    score = score_targets(detect_blobs(image, params), targets)
    assert score["found_1px"] >= 0.85 * len(targets), score


def test_printed_threshold_given_back_gives_the_same_blobs() -> None:
    image, _ = _load("cal1")
    derived = configure_detection([image])
    printed = float(f"{derived.params.threshold:.0f}")
    assert f"threshold {printed:.0f} grey levels above the local background" in derived.summary()
    again = configure_detection([image], {"threshold": printed})
    assert again.params.background_tile_px == derived.params.background_tile_px
    a = detect_blobs(image, derived.params.replace(threshold=printed))
    b = detect_blobs(image, again.params)
    assert len(a) == len(b) and np.array_equal(a.xy_px, b.xy_px)


@pytest.mark.parametrize("threshold", [None, 3.0, 40.0])
@pytest.mark.parametrize("name", ["cal4", "particles1"])
def test_memory_follows_the_pixels_at_any_threshold(name: str, threshold: float | None) -> None:
    image, _ = _load(name)
    given = {} if threshold is None else {"threshold": threshold}
    params = configure_detection([image], given).params
    tracemalloc.start()
    try:
        blobs = detect_blobs(image, params)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(blobs) > 10
    assert peak < BYTES_PER_PIXEL * image.size, f"{peak / image.size:.0f} bytes per pixel"


def test_a_frame_white_all_over_gives_no_blob_and_says_why() -> None:
    image, _ = _load("cal1")
    params = configure_detection([image]).params.replace(background_tile_px=0, threshold=1.0)
    assert len(detect_blobs(image, params)) == 0
    why = hopeless(image, params)
    assert why is not None and "above the threshold" in why
    assert hopeless(image, configure_detection([image]).params) is None
