"""Wand calibration speed: 600 wand fields x 6 cameras on the KISS-like rig.

The reference, timed in the same run, is :func:`scipy.optimize.least_squares` (trust
region, LSMR, the sparse Jacobian pattern) on the same adjustment of 100 fields, against
kisscal's sparse Levenberg-Marquardt with the Schur complement on the same 100 fields;
then the whole wand-on-rods calibration (3D wand finding, adjustment with outlier passes)
of 600 fields. Issue 16 asks for 600 fields x 6 cameras in under 60 s on 2 cores.

Recorded (2026-12-03, stop 67, 2 cores shared): the normal equations' batched products by
matmul instead of einsum, and ``W V^-1 W^T`` from the blocks above its diagonal written
whole into the grid: within this benchmark's noise here (Schur 100 fields 0.048-0.050 s
before, 0.049-0.053 s after; the 100 fields are too few for those products to weigh), but
4 wand-on-rods calibrations of 1200 fields in one process (the size of the session tests'
wand routes), paired by ``farm-bench -n 4`` with the previous version: 0.95x processor
time (whole process, scene and imports included), every figure of
``tests.bundle.wand_acceptance --quick`` identical.
"""

from __future__ import annotations

import numpy as np

from benchmarks._harness import best_of, report
from kisscal.bundle.adjust import WandPoses, adjust_bundle
from kisscal.bundle.params import BundleParams
from kisscal.bundle.wand import calibrate_on_control, select_fields
from kisscal.camera import Camera
from kisscal.synth.cameras import kiss_rig
from kisscal.synth.wand import WAND_MARKERS_MM, wand_trial
from tests.bundle.conftest import WandScene
from tests.bundle.test_wand import _rods


def main() -> list[str]:
    rig = kiss_rig(1)
    s = WandScene(rig, wand_trial(1, 600, 50.0), WAND_MARKERS_MM)
    table = s.blobs(ideal=True, noise_px=0.05)
    control, starts = _rods(s, 0.05, seed=1)

    def whole():
        return calibrate_on_control(
            table, starts, control, WAND_MARKERS_MM, s.sizes, s.ids, "wand01"
        )

    cal = whole()
    keep = np.arange(len(cal.fields)) < 100
    obs, wand, _ = select_fields(cal.observations, cal.result.wand, cal.fields, keep)
    start = tuple(
        Camera(c.K * [[1.002, 1, 1], [1, 0.998, 1], [1, 1, 1]], c.R, c.t, c.lens)
        for c in cal.cameras
    )
    moved = WandPoses(wand.centre_mm + 2.0, wand.direction)

    def solve(solver: str, budget: int):
        params = BundleParams(solver=solver, max_iterations=budget)
        return adjust_bundle(start, obs, WAND_MARKERS_MM, moved, control, params)

    ref = best_of(
        "least_squares (trf, lsmr), 100 fields",
        lambda: solve("least_squares", 100),
        100,
        "fields",
        repeat=1,
    )
    schur = best_of(
        "Schur Levenberg-Marquardt, 100 fields",
        lambda: solve("schur", 100),
        100,
        "fields",
        repeat=2,
    )
    costs = {k: float(np.sum(solve(k, 100).residuals_px ** 2)) for k in ("least_squares", "schur")}
    full = best_of("calibrate_on_control, 600 fields", whole, 600, "fields", repeat=2)
    return [
        f"rig: 6 cameras, {len(cal.fields)} wand fields, {len(cal.observations)} wand images",
        report(ref),
        report(schur, ref),
        f"final sum of squares: least_squares {costs['least_squares']:.4f}, "
        f"Schur {costs['schur']:.4f} px^2",
        report(full, ref),
        f"whole calibration {full.seconds:.2f} s (issue 16 bound: 60 s on 2 cores)",
    ]
