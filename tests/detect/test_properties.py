"""Detection on random images of random sizes, types and contents: a table or a clear error."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from kisscal.detect import detect_blobs
from kisscal.errors import KisscalError
from tests.detect.conftest import KISS

DTYPES = st.sampled_from(
    [np.uint8, np.uint16, np.float32, np.float64, np.bool_, np.int16, np.int64]
)
SHAPES = st.one_of(
    st.tuples(st.integers(1, 48), st.integers(1, 64)),
    st.tuples(st.integers(0, 3), st.integers(0, 3)),
    st.tuples(st.integers(1, 8), st.integers(1, 8), st.integers(1, 4)),
)


@given(arrays(DTYPES, SHAPES))
def test_detection_returns_a_table_or_a_clear_error(image: np.ndarray) -> None:
    try:
        blobs = detect_blobs(image, KISS)
    except KisscalError as exc:
        assert "\n" not in str(exc)
        return
    n = len(blobs)
    assert blobs.x_px.shape == (n,) and blobs.valid.dtype == bool
    h, w = image.shape[:2]
    valid = blobs.valid
    assert np.all((blobs.x_px[valid] >= -0.5) & (blobs.x_px[valid] <= w - 0.5))
    assert np.all((blobs.y_px[valid] >= -0.5) & (blobs.y_px[valid] <= h - 0.5))


@given(st.integers(8, 200), st.integers(8, 200), st.integers(0, 2**31 - 1))
def test_detection_of_random_noise_and_spots(h: int, w: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    image = rng.integers(0, 40, (h, w)).astype(np.uint8)
    for _ in range(rng.integers(0, 8)):
        y, x, r = rng.integers(0, h), rng.integers(0, w), rng.uniform(1, 6)
        yy, xx = np.ogrid[:h, :w]
        image[(yy - y) ** 2 + (xx - x) ** 2 <= r * r] = 230
    blobs = detect_blobs(image, KISS)
    assert np.all(np.isfinite(blobs.x_px)) and np.all(np.isfinite(blobs.y_px))
