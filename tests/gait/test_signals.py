"""The gait's Savitzky-Golay derivative, computed without importing scipy.signal."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.gait.signals import derivative, hysteresis_crossings, savgol_slope


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


def test_a_stay_cut_by_a_gap_is_a_crossing_a_brief_dip_is_not():
    """Forward then back: a stay below ``low`` shorter than ``hold`` is a dip when the
    signal rises again, a change of phase when a gap (the marker lost) cuts it; a stay
    cut by the signal's end is a stride cut by it."""
    y = np.array([2.0, 2, 2, 1, -1, -2, -2, 2, 2, 2, 2])
    band = np.ones_like(y)
    assert len(hysteresis_crossings(y, band, -band, hold=4)) == 0  # a dip
    lost = y.copy()
    lost[7:] = np.nan
    assert hysteresis_crossings(lost, band, -band, hold=4) == pytest.approx([3.5])
    assert len(hysteresis_crossings(y[:7], band[:7], -band[:7], hold=4)) == 0
