"""Fills expect the noise of what they are read off where the trial shows it (issue 27,
lowcost seed 362), against truth: a spline moved onto one camera's ray through samples
of two cameras, off along that camera's sight (kisscal.tracking.fill_spline), and a
body fill following donors noisier in its gap than on the stretches it was tried on
(kisscal.tracking.fill_anchor)."""

from __future__ import annotations

import numpy as np

from kisscal.tracking import TrackingParams
from kisscal.tracking.bodyfill import GapFill
from kisscal.tracking.fill_anchor import donor_noise
from kisscal.tracking.fill_spline import context_noise, sight_noise, spline_fill
from kisscal.tracking.tracks import FILLED_RIGID
from tests.tracking.test_fill_anchor import _path

PARAMS = TrackingParams()


def test_a_spline_on_a_ray_expects_the_noise_along_its_sight() -> None:
    truth = _path()
    centre = truth.mean(axis=0) + np.array([500.0, -3000.0, 800.0])
    sight = truth - centre
    sight /= np.linalg.norm(sight, axis=1, keepdims=True)
    lo, hi, n = 60, 64, PARAMS.fill_context_fields
    rng = np.random.default_rng(362)
    along, third, claim = [], [], []
    for _ in range(60):
        # a point of two cameras: off along each one's sight, here the one left seeing it
        series = truth + rng.normal(0.0, 3.0, (len(truth), 1)) * sight
        series += rng.normal(0.0, 0.2, truth.shape)
        series[lo:hi] = np.nan
        got = spline_fill(series, series[None], 0, lo, hi, PARAMS)
        assert got is not None
        along.append(np.sum((got[0] - truth[lo:hi]) * sight[lo:hi], axis=1))
        third.append(context_noise(series, None, lo, hi, n) / np.sqrt(3.0))
        claim.append(sight_noise(series, centre[None], lo, hi, n))
    true = float(np.sqrt(np.mean(np.square(along))))  # what the camera's ray leaves
    assert true > 1.5 * float(np.mean(third))  # a third of the noise: claims too little
    assert 0.7 * true < float(np.mean(claim)) < 1.5 * true
    assert np.isnan(sight_noise(series, np.zeros((0, 3)), lo, hi, n))


def test_a_body_fill_expects_its_donors_noise_in_its_gap() -> None:
    truth = _path()
    rng = np.random.default_rng(3620)
    dense = np.stack([truth, truth + [0.0, 240.0, 0.0], truth + [-150.0, 120.0, 0.0]])
    fill = GapFill(2, 20, 26, FILLED_RIGID, 1.0, (0, 1))
    assert donor_noise([(truth[20:46], fill)], dense)[0][1].expected_error_mm == 1.0
    # donors seen by two cameras in the gap: 2 mm RMS off, mostly along one sight
    noisy = dense.copy()
    off = rng.normal(0.0, 1.0, (2, 26, 1)) * [1.8, 0.6, 0.6] / np.sqrt(1.8**2 + 0.72)
    noisy[:2, 20:46] += 2.0 * off
    true = float(np.sqrt(np.mean(np.sum((noisy[:2, 20:46] - dense[:2, 20:46]) ** 2, axis=2))))
    got = donor_noise([(truth[20:46], fill)], noisy)[0][1]
    assert 0.75 * true < got.expected_error_mm < 1.33 * true
    assert (
        donor_noise([(truth[20:46], GapFill(2, 20, 26, FILLED_RIGID, 1.0))], noisy)[0][
            1
        ].expected_error_mm
        == 1.0
    )  # a spline has no donors
