"""The census of OpenPTV's targets: each extra detection lands in the class it was built for."""

from __future__ import annotations

import numpy as np

from kisscal.detect import DetectionParams
from tests.detect.openptv_census import EXTRA_CLASSES, PEAK_CLASSES, _extras, census
from tests.detect.real_acceptance import OpenptvView


def test_extra_detections_fall_in_the_class_they_were_built_for() -> None:
    grey = np.zeros((60, 80), np.uint8)
    grey[40, 10] = 200  # one bright pixel: too small for OpenPTV (4 pixels, 150 summed)
    grey[39:42, 59:62] = 100  # 9 pixels, 900 summed: OpenPTV would take it
    grey[50:58, 20:50] = 60  # 240 pixels: more than OpenPTV's largest target (200 here)
    targets = np.array([[10.0, 10.0], [30.0, 10.0]])
    blobs = np.array(
        [
            [10.4, 10.0],  # target 0 itself (not an extra)
            [12.5, 10.0],  # a second spot beside target 0: piece
            [32.5, 10.0],  # target 1 seen 2.5 px off: offset
            [40.0, 25.0],  # nothing in OpenPTV's image: faint
            [10.0, 40.0],  # the bright pixel: small
            [60.0, 40.0],  # the 3 x 3 block: other
            [30.0, 54.0],  # a piece of the lit band: lit
        ]
    )
    view = OpenptvView(targets, grey, 9.0, 4, 150.0, 200)
    got = _extras(blobs, targets, view)
    assert [got[k] for k in EXTRA_CLASSES] == [1, 1, 1, 1, 1, 1]


def test_missed_targets_fall_in_the_peaks_routes_classes() -> None:
    grey = np.zeros((70, 110), np.uint8)
    grey[19:22, 19:22] = 100  # found
    grey[19:22, 39:42] = 5  # below the threshold of 10
    grey[39:41, 18:24] = 100  # one spot, two targets: merged
    grey[40, 60] = 200  # one pixel: too small
    grey[39:42, 79:82] = 100  # its target 2 px off: offset
    grey[39:42, 0:3] = 100  # on the border
    targets = np.array(
        [[20, 20], [40, 20], [19, 39.5], [22, 39.5], [60, 40], [82, 40], [1, 40]], dtype=float
    )
    params = DetectionParams(route="peaks", threshold=10.0, min_pixels=3)
    got = census(grey, targets, params)
    assert got["found"] == 1
    expected = dict.fromkeys(PEAK_CLASSES, 0) | {
        "peak_below_threshold": 1,
        "peak_merged": 2,
        "peak_too_small": 1,
        "peak_offset": 1,
        "peak_border": 1,
    }
    assert {k: got[k] for k in PEAK_CLASSES} == expected
