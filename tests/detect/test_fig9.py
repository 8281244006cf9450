"""The artificial test image of Shafiq et al. 2001, section 3.1 (Fig. 9): staged results."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from fixtures.fig9 import INVALID, fig9_params, make_fig9, truth_xy
from kisscal.detect import blobs as fl
from kisscal.detect import detect_blobs


@pytest.fixture(scope="module")
def image() -> np.ndarray:
    return make_fig9()


def test_fixture_png_is_the_generated_image(image):
    from pathlib import Path

    png = cv2.imread(str(Path("fixtures/fig9.png")), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(png, image)


def test_without_advanced_analysis_ten_groups(image):
    # Fig. 9(b): overlapped, long and wide pairs come out as one group each, and the ul pair
    # as a cluster of three (two sub-marker fragments).
    blobs = detect_blobs(image, fig9_params().without_advanced_analysis())
    assert len(blobs) == 10
    assert blobs.valid.all()


def test_sub_marker_merge_gives_eight(image):
    params = fig9_params().without_advanced_analysis().replace(merge_submarkers=True)
    blobs = detect_blobs(image, params)
    assert len(blobs) == 8
    assert np.count_nonzero(blobs.flags & fl.MERGED) == 1


def test_all_tests_find_the_twelve_markers(image):
    blobs = detect_blobs(image, fig9_params().replace(apply_size_limits=False))
    assert len(blobs) == 12
    truth = np.array(list(truth_xy().values()))
    d = np.hypot(blobs.x_px[:, None] - truth[:, 0], blobs.y_px[:, None] - truth[:, 1])
    # one detection per marker, each within a pixel of its centre (markers are 12 x 6 px)
    assert sorted(np.argmin(d, axis=0).tolist()) == list(range(12))
    assert d.min(axis=0).max() < 1.0
    for bit, n in ((fl.SPLIT_UL, 2), (fl.SPLIT_UR, 2), (fl.SPLIT_WIDE, 2), (fl.SPLIT_LONG, 2)):
        assert np.count_nonzero(blobs.flags & bit) == n


def test_size_limits_mark_four_invalid(image):
    blobs = detect_blobs(image, fig9_params())
    assert len(blobs) == 12
    assert np.count_nonzero(~blobs.valid) == 4
    truth = truth_xy()
    for name in INVALID:
        cx, cy = truth[name]
        i = np.argmin(np.hypot(blobs.x_px - cx, blobs.y_px - cy))
        assert not blobs.valid[i]
        expected = fl.TOO_LARGE if name.startswith("large") else fl.TOO_SMALL
        assert blobs.flags[i] & expected


@pytest.mark.parametrize(
    "switch", ["merge_submarkers", "split_overlaps", "split_long_wide", "apply_size_limits"]
)
def test_each_switch_matters(image, switch):
    full = detect_blobs(image, fig9_params())
    without = detect_blobs(image, fig9_params().replace(**{switch: False}))
    assert (len(without), int(without.valid.sum())) != (len(full), int(full.valid.sum()))
