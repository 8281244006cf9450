"""Stationary false detections are removed; moving markers are kept."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.recon.params import ReconParams
from kisscal.recon.stationary import false_detections, stationary_mask

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


def _still_and_moving(n_fields: int) -> tuple:
    """Camera 0: a fixed spot (an LED, a reflection) and a marker moving 4 px per field."""
    field = np.repeat(np.arange(n_fields), 2)
    uv = np.tile(np.array([[200.0, 100.0], [0.0, 0.0]]), (n_fields, 1))
    uv[1::2] = [[100.0 + 4 * f, 150.0] for f in range(n_fields)]
    return field, np.zeros(len(field), dtype=int), uv


def test_a_long_moving_trial_loses_its_stationary_spots() -> None:
    field, camera, uv = _still_and_moving(120)
    still, test = false_detections(field, camera, uv, ReconParams(), rate_hz=50.0)
    assert test == "motion"
    assert still[0::2].all() and not still[1::2].any()


@pytest.mark.parametrize(("n_fields", "rate_hz"), [(1, 50.0), (20, 50.0), (99, 50.0), (300, 200.0)])
def test_a_trial_too_short_to_judge_keeps_every_detection(n_fields: int, rate_hz: float) -> None:
    # under 2 s a marker may have stood still all along: stillness proves nothing
    field, camera, uv = _still_and_moving(n_fields)
    still, test = false_detections(field, camera, uv, ReconParams(), rate_hz=rate_hz)
    assert test == "short" and not still.any()


def test_a_long_trial_where_nothing_moves_is_not_emptied() -> None:
    field, camera, uv = _still_and_moving(300)
    uv[1::2] = [300.0, 150.0]  # the marker stands still too: a standing trial
    still, test = false_detections(field, camera, uv, ReconParams(), rate_hz=50.0)
    assert test == "short" and not still.any()
    off = ReconParams(stationary_filter=False)
    assert false_detections(field, camera, uv, off, rate_hz=50.0)[1] == "off"


def test_a_one_field_static_target_reconstructs_fully_and_its_leds_are_dropped() -> None:
    from kisscal.dlt.model import project
    from kisscal.recon import reconstruct_trial
    from kisscal.recon.epipolar import camera_centre_mm

    dlts = make_rig(2)
    rng = np.random.default_rng(2)
    xyz = random_markers(rng, 1, 200)[0]
    centres = np.array([camera_centre_mm(L) for L in dlts])
    field, camera, uv = [], [], []
    for c in range(6):
        # every other camera's LED ring in front of this one, as a blob at its epipole
        front = np.delete(centres, c, axis=0)
        front = front[front @ dlts[c][8:11] + 1.0 > 0]
        p = np.vstack([project(dlts[c], xyz), project(dlts[c], front)])
        p += rng.normal(0, 0.05, p.shape)
        field += [0] * len(p)
        camera += [c] * len(p)
        uv.append(p)
    pts = reconstruct_trial(field, camera, np.concatenate(uv), dlts)
    assert pts.stationary_test == "short"
    d = np.linalg.norm(pts.xyz_mm[:, None] - xyz[None], axis=2)
    assert len(pts) == 200 and d.min(axis=1).max() < 2.0
    assert len(np.unique(d.argmin(axis=1))) == 200
