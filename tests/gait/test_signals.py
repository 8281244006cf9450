"""The gait signal helpers written on numpy agree with scipy.signal's definitions."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import find_peaks as scipy_peaks
from scipy.signal import savgol_filter

from kisscal.gait.signals import find_peaks, quadratic_slope


@pytest.mark.parametrize("n", [5, 7, 11])
def test_quadratic_slope_is_the_savitzky_golay_first_derivative(n: int) -> None:
    rng = np.random.default_rng(n)
    t = np.arange(60) / 50.0
    x = np.column_stack([np.sin(3 * t), t**2]) + rng.normal(0, 0.01, (60, 2))
    want = savgol_filter(x, n, 2, deriv=1, delta=0.02, axis=0)
    assert np.allclose(quadratic_slope(x, n, 0.02), want, rtol=0, atol=1e-9)
    # a quadratic's slope is exact everywhere, the ends included
    assert np.allclose(quadratic_slope(3 * t**2 - t, n, 0.02), 6 * t - 1)


def test_quadratic_slope_keeps_the_shape_of_three_dimensional_samples() -> None:
    x = np.random.default_rng(1).normal(size=(30, 4, 3))
    want = savgol_filter(x, 7, 2, deriv=1, delta=0.5, axis=0)
    assert np.allclose(quadratic_slope(x, 7, 0.5), want, atol=1e-9)


@pytest.mark.parametrize("seed", range(12))
def test_find_peaks_matches_scipy_with_prominence_and_distance(seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 400))
    y = np.cumsum(rng.normal(size=n)) + np.sin(np.arange(n) / 7.0) * 5
    y = np.round(y, 0 if seed % 3 == 0 else 6)  # flat tops when rounded coarsely
    prominence = float(rng.uniform(0, 4))
    distance = int(rng.integers(1, 25))
    want = scipy_peaks(y, prominence=prominence, distance=distance)[0]
    assert np.array_equal(find_peaks(y, prominence, distance), want)


def test_find_peaks_of_flat_tops_and_edges() -> None:
    y = np.array([5.0, 1, 3, 3, 3, 0, 2, 2, 4])
    assert find_peaks(y, 0.0, 1).tolist() == [3]  # the middle of the flat top; no end
