"""Reconstruction speed: fields per second of matching + triangulation on the gait trial.

The 6-camera, 15-marker synthetic gait trial (seed 1, 500 fields) is projected to ideal
pixels with 0.05 px noise, plus the other cameras' LEDs and two random blobs per camera
and field (the acceptance scenario of tests/recon). Reference: triangulating the true
correspondences alone (no matching), timed in the same run. The closing line holds
reconstruct_trial with the default parameters (the session's strategy) against issue 18's
bar of 5000 fields/s on one core.
"""

from __future__ import annotations

import time

import numpy as np

from benchmarks._harness import best_of, report

N_FIELDS = 500
BAR_FIELDS_PER_S = 5000.0  # issue 18: reconstruction on one core


def main() -> list[str]:
    from kisscal.dlt.triangulate import triangulate_observations
    from kisscal.recon import ReconParams, reconstruct_trial, stationary_mask
    from kisscal.recon.match import match_trial
    from kisscal.recon.params import DEFAULT_PARAMS
    from tests.recon.synth_trials import make_trial

    trial = make_trial("walk", 1, n_fields=N_FIELDS)
    n_fields = len(trial.xyz)
    lines = [
        f"gait trial: {n_fields} fields, {trial.dlts.shape[0]} cameras, "
        f"{len(trial.field)} blobs ({int((trial.truth < 0).sum())} ghosts)"
    ]
    still = stationary_mask(trial.field, trial.camera, trial.uv)
    keep = ~still
    f, c, uv, truth = trial.field[keep], trial.camera[keep], trial.uv[keep], trial.truth[keep]
    # reference: the true correspondences, triangulated without any matching
    real = truth >= 0
    point = f[real] * 100 + truth[real]
    _, point = np.unique(point, return_inverse=True)
    ref = best_of(
        "triangulate true matches (reference)",
        lambda: triangulate_observations(trial.dlts, point, c[real], uv[real], None, 2),
        n_fields,
        "fields",
    )
    lines.append(report(ref))
    triple = ReconParams(strategy="triple")
    lines.append(
        report(
            best_of(
                "triple: match + triangulate",
                lambda: match_trial(f, c, uv, trial.dlts, triple),
                n_fields,
                "fields",
            ),
            ref,
        )
    )
    whole = best_of(
        "triple: reconstruct_trial (with filter)",
        lambda: reconstruct_trial(trial.field, trial.camera, trial.uv, trial.dlts),
        n_fields,
        "fields",
    )
    lines.append(report(whole, ref))
    # CPU seconds of the same call (best of 3): the one-core rate even when other work
    # shares the machine, and above the wall rate if a library ran threads
    cpu = float("inf")
    for _ in range(3):
        c0 = time.process_time()
        reconstruct_trial(trial.field, trial.camera, trial.uv, trial.dlts)
        cpu = min(cpu, time.process_time() - c0)
    head = f < 100
    central = ReconParams(strategy="central")
    lines.append(
        report(
            best_of(
                "central: match + triangulate",
                lambda: match_trial(f[head], c[head], uv[head], trial.dlts, central),
                100,
                "fields",
                repeat=1,
            ),
            ref,
        )
    )
    met = "met" if whole.per_second >= BAR_FIELDS_PER_S else "NOT met"
    lines.append(
        f"reconstruct_trial, default strategy {DEFAULT_PARAMS.strategy!r}: "
        f"{whole.per_second:.0f} fields/s ({n_fields / cpu:.0f} per CPU second); issue 18 "
        f"bar: {BAR_FIELDS_PER_S:.0f} fields/s on one core: {met}"
    )
    return lines
