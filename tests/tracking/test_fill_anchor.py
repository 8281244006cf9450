"""A fill read off fields placed before it in its gap expects their error too
(kisscal.tracking.fill_anchor): a spline between a one-camera placement 3 mm off and
the marker's measured samples, on a synthetic walk's smooth path."""

from __future__ import annotations

import numpy as np

from kisscal.tracking import TrackingParams
from kisscal.tracking.bodyfill import GapFill
from kisscal.tracking.fill_body import spline_or_body
from kisscal.tracking.gap_record import Gap
from kisscal.tracking.tracks import FILLED, FILLED_RIGID

PARAMS = TrackingParams()


def _path(n: int = 120) -> np.ndarray:
    """A marker's path at 100 Hz: forward at 1.2 m/s, swaying and bobbing."""
    t = np.arange(n) / 100.0
    return np.column_stack([1200.0 * t, 30.0 * np.sin(2.0 * t), 900.0 + 20.0 * np.sin(12.0 * t)])


def test_a_spline_off_placed_fields_expects_their_error() -> None:
    truth = _path()
    rng = np.random.default_rng(4)
    dense = (truth + rng.normal(0.0, 0.2, truth.shape))[None].copy()
    lo, hi = 50, 66
    dense[0, lo:hi] = np.nan
    # the gap's first 12 fields placed on one camera's rays, 3 mm off along its sight
    off = np.array([0.0, 1.8, 2.4])
    placed = truth[lo : lo + 12] + off
    dense[0, lo : lo + 12] = placed
    made = [(placed, GapFill(0, lo, 12, FILLED_RIGID, 3.0, (), 12))]
    gap = Gap(dense, 0, lo, hi, PARAMS, None, None, np.zeros(hi - lo, bool), list(made))
    assert spline_or_body(gap, lo + 12, hi, PARAMS).all()
    xyz, fill = gap.out[-1]
    assert fill.status == FILLED and fill.first_field == lo + 12
    true_rms = np.sqrt(np.mean(np.sum((xyz - truth[lo + 12 : hi]) ** 2, axis=1)))
    assert true_rms > 0.5  # the placed fields' error carried into the spline
    assert true_rms <= 2.0 * fill.expected_error_mm


def test_fills_far_from_the_spline_leave_its_expectation() -> None:
    truth = _path()
    rng = np.random.default_rng(4)
    dense = (truth + rng.normal(0.0, 0.2, truth.shape))[None].copy()
    lo, hi = 62, 66
    dense[0, lo:hi] = np.nan
    far = [(truth[20:30] + 3.0, GapFill(0, 20, 10, FILLED_RIGID, 3.0, (), 10))]
    expected = []
    for made in ([], far):
        gap = Gap(dense, 0, lo, hi, PARAMS, None, None, np.zeros(hi - lo, bool), list(made))
        assert spline_or_body(gap, lo, hi, PARAMS).all()
        expected.append(gap.out[-1][1].expected_error_mm)
    assert expected[0] == expected[1] < 3.0
