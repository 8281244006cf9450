"""The local background's 5 x 5 rank filter against a plain numpy median."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.detect.background import _rank5


@pytest.mark.parametrize("shape", [(5, 5), (6, 9), (37, 95), (5, 300)])
def test_the_median_of_each_5x5_neighbourhood_edges_repeated(shape):
    rng = np.random.default_rng(shape[1])
    maps = (
        rng.normal(20, 5, shape).astype(np.float32),
        (rng.integers(0, 4, shape) * 0.5).astype(np.float32),  # many ties
    )
    for small in maps:
        padded = np.pad(small, 2, mode="edge")
        windows = np.lib.stride_tricks.sliding_window_view(padded, (5, 5))
        expected = np.median(windows.reshape(*shape, 25), axis=-1).astype(np.float32)
        got = _rank5(small, 0.5)
        assert got.dtype == np.float32
        assert np.array_equal(got, expected)
        lower = np.sort(windows.reshape(*shape, 25), axis=-1)[..., 6]
        assert np.array_equal(_rank5(small, 0.25), lower)
