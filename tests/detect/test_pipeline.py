"""detect_blobs / detect_sequence: inputs, outputs, bad input."""

from __future__ import annotations

from functools import partial

import numpy as np
import pytest

from kisscal.detect import Blobs, detect_blobs, detect_sequence
from kisscal.errors import KisscalError
from tests.detect.conftest import KISS, render

TRUTH = np.array([[100.2, 50.7], [300.6, 120.1], [500.5, 200.4], [650.1, 30.3]])


def test_black_image_gives_empty_table():
    blobs = detect_blobs(np.zeros((291, 752), dtype=np.uint8), KISS)
    assert len(blobs) == 0
    assert isinstance(blobs, Blobs)
    assert len(blobs.valid_only()) == 0


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        (np.zeros((0, 5), dtype=np.uint8), "empty"),
        (np.zeros((10, 10, 3), dtype=np.uint8), "3 channels"),
        (np.zeros((10, 10), dtype=np.int32), "dtype"),
        (np.zeros(10, dtype=np.uint8), "2-D"),
        ("image.png", "str"),
    ],
)
def test_bad_input_raises_one_clear_error(bad, message):
    with pytest.raises(KisscalError, match=message):
        detect_blobs(bad, KISS)


def test_bad_parameters_raise():
    with pytest.raises(KisscalError, match="min_ratio"):
        KISS.replace(min_ratio=1.2)
    with pytest.raises(KisscalError, match="unknown parameter"):
        KISS.replace().replace(treshold=3)
    with pytest.raises(KisscalError, match="threshold must be a finite number"):
        KISS.replace(threshold="bright")
    with pytest.raises(KisscalError, match="merge_submarkers must be true or false"):
        KISS.replace(merge_submarkers=1)
    with pytest.raises(KisscalError, match="detach_kernel_px must be odd"):
        KISS.replace(detach_kernel_px=(10, 7))
    with pytest.raises(KisscalError, match="max_pixels must be > 0 px"):
        KISS.replace(max_pixels=0)


def test_boolean_and_grey_images_agree_on_groups():
    grey = render(TRUTH, 3.5)
    params = KISS.replace()
    from_grey = detect_blobs(grey, params)
    from_bool = detect_blobs(grey >= params.threshold, params)
    assert np.array_equal(from_grey.pixels, from_bool.pixels)
    # a thresholded image has no grey levels: its centroid is the binary one
    assert np.array_equal(from_bool.x_px, from_bool.x_binary_px)
    assert np.allclose(from_grey.x_binary_px, from_bool.x_binary_px)


def test_uint16_and_float_images():
    grey = render(TRUTH, 3.5)
    ref = detect_blobs(grey, KISS)
    as16 = detect_blobs(grey.astype(np.uint16) * 257, KISS)  # grey levels on the 8-bit scale
    asf = detect_blobs(grey.astype(np.float32), KISS)
    assert np.allclose(as16.x_px, ref.x_px)
    assert np.allclose(asf.x_px, ref.x_px)


def test_markers_at_the_image_border_are_found():
    truth = np.array([[1.5, 100.3], [750.2, 150.0], [400.0, 0.8], [200.0, 289.9]])
    blobs = detect_blobs(render(truth, 3.0), KISS)
    assert len(blobs.valid_only()) == 4


def _frame(i: int) -> np.ndarray:
    return render(TRUTH + np.array([i * 0.1, 0.0]), 3.5)


def test_sequence_matches_single_images_in_order():
    frames = [_frame(i) for i in range(5)]
    serial = [detect_blobs(f, KISS) for f in frames]
    for result in (
        detect_sequence(frames, KISS, workers=2, chunksize=2),
        detect_sequence(_frame, KISS, count=5, workers=2, chunksize=2),
        detect_sequence(partial(_frame), KISS, count=5, workers=1),
    ):
        assert len(result) == 5
        for a, b in zip(result, serial, strict=True):
            assert np.array_equal(a.x_px, b.x_px)


def test_sequence_needs_count_with_a_loader():
    with pytest.raises(KisscalError, match="count"):
        detect_sequence(_frame)


def test_16_bit_frames_give_the_same_blobs_as_8_bit() -> None:
    """A 16-bit camera frame of the same scene finds the same markers at the same places."""
    from kisscal.synth.cameras import kiss_rig
    from kisscal.synth.motion import walking_trial
    from kisscal.synth.render import RenderParams
    from kisscal.synth.scene import image_rng, led_spots, render_markers, visibility

    rig = kiss_rig(2)
    cam = rig[0]
    motion = walking_trial(2, 60)
    vis = visibility(cam, motion)
    params = RenderParams()
    image, _ = render_markers(
        cam,
        motion.xyz_mm[30],
        vis[30],
        led_spots(cam, rig, params),
        image_rng(2, "trial", 0, 30),
        params,
    )
    b8 = detect_blobs(image, KISS)
    b16 = detect_blobs(image.astype(np.uint16) * 257, KISS)
    assert len(b8) == len(b16) > 5
    np.testing.assert_allclose(b16.x_px, b8.x_px, atol=1e-3)
    np.testing.assert_array_equal(b16.valid, b8.valid)
