"""The busy benchmark frame: a bright uneven surround, a thousand dots, their true centres."""

from __future__ import annotations

import cv2
import numpy as np

from kisscal.synth.busy import busy_frame


def test_busy_frame_is_busy_and_every_dot_stands_out_locally() -> None:
    image, centres = busy_frame(3)
    assert image.shape == (1024, 1280) and image.dtype == np.uint8 and centres.shape == (1000, 2)
    # at a threshold made for a dark background, the surround is one huge blob
    _, _, stats, _ = cv2.connectedComponentsWithStats((image >= 40).astype(np.uint8), 8)
    assert stats[1:, cv2.CC_STAT_AREA].max() > 300_000
    # the background is uneven: from dark to saturated
    assert np.percentile(image, 5) < 40 and (image == 255).sum() > 5000
    # every dot is brighter than the ring of pixels around it by a clear margin
    u, v = np.rint(centres).astype(int).T
    ring = np.stack(
        [image[v + dv, u + du] for du, dv in ((-9, 0), (9, 0), (0, -9), (0, 9))], axis=1
    )
    contrast = image[v, u].astype(float) - np.median(ring, axis=1)
    assert np.percentile(contrast, 1) > 60
    # no two dots touch
    d = np.linalg.norm(centres[:, None] - centres[None], axis=2) + np.eye(len(centres)) * 1e9
    assert d.min() > 14


def test_busy_frame_is_a_pure_function_of_its_seed() -> None:
    a, ca = busy_frame(5, (400, 320), n_dots=80)
    b, cb = busy_frame(5, (400, 320), n_dots=80)
    c, _ = busy_frame(6, (400, 320), n_dots=80)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(ca, cb)
    assert not np.array_equal(a, c)
