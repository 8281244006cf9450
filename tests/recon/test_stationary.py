"""Stationary false detections are removed; moving markers are kept."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.recon.params import ReconParams
from kisscal.recon.stationary import stationary_mask

from .rig import make_rig, make_table, random_markers


def test_leds_are_flagged_and_markers_are_not() -> None:
    rng = np.random.default_rng(0)
    dlts = make_rig(0)
    xyz = random_markers(rng, 100, 10)
    field, camera, uv, truth, _ = make_table(rng, dlts, xyz, n_leds=3, n_noise=1)
    leds = truth == -1
    still = stationary_mask(field, camera, uv, radius_px=1.5, fraction=0.5)
    # every LED blob (3 per camera per field) goes, and no true marker blob
    assert still.sum() >= 3 * 6 * 100
    assert not np.any(still & (truth >= 0))
    # noise blobs move at random: they stay
    assert (still & leds).sum() <= 3 * 6 * 100 + 2


def test_a_marker_that_stands_still_is_kept_below_the_fraction() -> None:
    field = np.arange(100)
    uv = np.where(field[:, None] < 40, [[100.0, 50.0]], [[0.0, 0.0]] + field[:, None] * 3.0)
    still = stationary_mask(field, np.zeros(100, int), uv, 1.5, 0.5)
    assert not still.any()
    still = stationary_mask(field, np.zeros(100, int), uv, 1.5, 0.3)
    assert still[:40].all() and not still[40:].any()


def test_bad_input_raises() -> None:
    with pytest.raises(KisscalError):
        stationary_mask([0, 1], [0], [[1, 2], [3, 4]])
    with pytest.raises(KisscalError):
        stationary_mask([0], [0], [[np.nan, 2]])
    with pytest.raises(KisscalError):
        ReconParams(stationary_fraction=1.5)
    with pytest.raises(KisscalError):
        ReconParams(strategy="nearest")
