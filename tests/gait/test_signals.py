"""The gait's Savitzky-Golay derivative, computed without importing scipy.signal."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.gait.signals import derivative, savgol_slope


@pytest.mark.parametrize(("n", "shape"), [(5, (40,)), (11, (11,)), (21, (300, 3)), (7, (60, 2, 3))])
def test_savgol_slope_is_scipys_savgol_filter_bit_for_bit(n, shape):
    from scipy.signal import savgol_filter

    rng = np.random.default_rng(n)
    x = np.cumsum(rng.normal(0, 1, shape), axis=0) * 10
    expected = savgol_filter(x, n, 2, deriv=1, delta=1 / 120, axis=0)
    assert np.array_equal(savgol_slope(x, n, 1 / 120), expected)


def test_derivative_of_a_parabola_is_exact_to_its_ends_and_keeps_gaps():
    t = np.arange(200) / 100.0
    x = 3 * t**2 - 2 * t + 1
    x[90:95] = np.nan
    v = derivative(x, 100.0, 100.0)
    ok = np.isfinite(v)
    assert not ok[90:95].any() and ok.sum() == 195
    assert np.allclose(v[ok], (6 * t - 2)[ok], atol=1e-9)
