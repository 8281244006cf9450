"""The two-marker fills know their error: expected against true on a synthetic leg whose
foot pitches and turns (kisscal.tracking.bodyfill.axis_fill, kisscal.tracking.fill_hinge, and
at the trial's ends kisscal.tracking.fill_ends.one_sided).

Case of both: a heel about the ankle-toe axis in a gap where the foot pitches. Its turn
counted from the mediolateral direction swings the heel, while the stretches its error was
measured on counted it from the vertical (axis fill: 0.8 mm expected, 13.6 true; hinge
fill, seed 2, 200-237: 1.25 mm expected, 5.17 true).
"""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.tracking import TrackingParams
from kisscal.tracking.bodyfill import axis_fill, fill_candidates
from kisscal.tracking.fill_ends import one_sided
from kisscal.tracking.fill_hinge import hinge_fill, neighbour_hinge_fill
from kisscal.tracking.tracks import FILLED_RIGID
from tests.tracking.test_fill_neighbour_hinge import _leg

PARAMS = TrackingParams()
GAPS = ((200, 237), (50, 90), (150, 175), (220, 260))


@pytest.mark.parametrize(
    ("methods", "min_checked"),
    [
        (((FILLED_RIGID, axis_fill),), 4),
        (((FILLED_RIGID, hinge_fill), (FILLED_RIGID, neighbour_hinge_fill)), 20),
    ],
    ids=["axis", "hinges"],
)
def test_the_fill_expects_the_error_it_makes(methods: tuple, min_checked: int) -> None:
    checked = 0
    for seed in (1, 2):
        xyz, truth = _leg(seed)
        for lo, hi in GAPS:
            for t in range(len(xyz)):
                dense = xyz.copy()
                dense[t, lo:hi] = np.nan
                for c in fill_candidates(dense, t, lo, hi, PARAMS, methods):
                    if not np.isfinite(c.fill.expected_error_mm):
                        continue  # no stretch to measure it on: never chosen
                    miss = c.xyz_mm - truth[t, lo:hi]
                    err = np.sqrt(np.mean(np.sum(miss**2, axis=1)))
                    assert err <= 2.0 * c.fill.expected_error_mm + 1.0, (seed, lo, t, c.fill)
                    checked += 1
    assert checked >= min_checked


def test_the_end_fill_expects_the_error_it_makes() -> None:
    # the same heel at the trial's ends, carried by the ankle-toe axis from one side
    # (fill_ends.one_sided): its turn counted from the end's lab direction while its
    # stretches counted it from theirs, it expected 0.8 mm and missed by 13.8. From one
    # side the stretches cannot be matched in phase to the end (the target's move across
    # it is unknown), so the bound is looser than the gaps'; the foot only, as the shank's
    # turn about its own axis follows no lab direction (the three-marker fill carries it)
    checked = 0
    for seed in (1, 2):
        xyz, truth = _leg(seed, 400)
        for start in range(0, 100, 10):
            for k in (20, 37, 50):
                for after, (lo, hi) in ((True, (0, k)), (False, (300 - k, 300))):
                    for t in (3, 4):
                        dense = xyz[:, start : start + 300].copy()
                        dense[t, lo:hi] = np.nan
                        method = ((FILLED_RIGID, one_sided(after, axis=True)),)
                        for c in fill_candidates(dense, t, lo, hi, PARAMS, method):
                            if not np.isfinite(c.fill.expected_error_mm):
                                continue
                            miss = c.xyz_mm - truth[t, start + lo : start + hi]
                            err = np.sqrt(np.mean(np.sum(miss**2, axis=1)))
                            assert err <= 4.0 * c.fill.expected_error_mm + 1.0, (seed, start, lo, t)
                            checked += 1
    assert checked >= 40
