"""Time of the gap fill's donor check (:func:`kisscal.tracking.fill_donors.misfit_fields`)
on a long trial, against its definition taken literally in the same run (every donor
against every track over the whole trial: the test's reference,
``tests.tracking.test_fill_donors._misfits_over_every_track``).

Trial: 40 tracks (rigid feet of three markers, noise 0.3 mm) of 3000 fields, each with a
gap somewhere and a quarter of them hidden through the filled gap (100 fields), three
donors, one of them pulled 6 mm for 10 fields. Time: this process's CPU time, best of
5, taken in turns; the two must flag the same fields.

Recorded (2026-12-03, 2 cores shared with a test run, commit after 4734ec6): every
track over the whole trial 0.0158 s, misfit_fields 0.0050 s (0.31x), the same 61 fields
flagged. In a real trial of 200 fields and more tracks (the racing-propulsion C3D test)
the check ran for every candidate fill of every gap and was most of the tracking time.
"""

from __future__ import annotations

import time

import numpy as np

from benchmarks._harness import best_of_pair, report
from kisscal.tracking import TrackingParams
from kisscal.tracking.fill_donors import misfit_fields
from tests.tracking.test_fill_donors import _misfits_over_every_track, _rolling_foot

N_FEET, N_FIELDS, GAP = 14, 3000, (1500, 1600)


def _trial() -> np.ndarray:
    rng = np.random.default_rng(3)
    feet = [_rolling_foot(s, N_FIELDS) + rng.normal(0, 400, 3) for s in range(N_FEET)]
    dense = np.concatenate(feet)[:40]
    for i in range(len(dense)):
        start = rng.integers(0, N_FIELDS - 200)
        dense[i, start : start + rng.integers(5, 200)] = np.nan
    dense[rng.choice(np.arange(3, len(dense)), 10, replace=False), GAP[0] : GAP[1]] = np.nan
    dense[0, GAP[0] + 20 : GAP[0] + 30] += [0.0, 6.0, 0.0]  # a donor pulled by a merged blob
    return dense


def main() -> list[str]:
    dense, params, donors = _trial(), TrackingParams(), (0, 1, 3)
    args = (dense, 2, donors, *GAP, params)
    ref, ours = best_of_pair(
        ("every track, whole trial", lambda: _misfits_over_every_track(*args)),
        ("misfit_fields", lambda: misfit_fields(*args)),
        1,
        "check",
        clock=time.process_time,
    )
    same = np.array_equal(misfit_fields(*args), _misfits_over_every_track(*args))
    flags = int(misfit_fields(*args).sum())
    return [report(ref), report(ours, ref), f"same fields flagged: {same} ({flags})"]
