"""Issue 11's end-to-end acceptance: every preset, synthesised and run with no ``[detection]``.

Run from the repository root::

    python -m tests.session.presets_acceptance kiss:31 modern:31 lowcost:31
    python -m tests.session.presets_acceptance lowcost:32 --fields 200 --work /tmp/acc

Per ``PRESET:SEED``: ``kisscal synth`` (no walking5 trial) then ``kisscal run`` with the
detection settings the session derives for itself, and one JSON line of figures against
the synthetic truth:

- ``dots_min``: fewest grid dots any camera's linearisation used (of 300);
- ``grid_ratio_max``: the largest ratio, over the cameras, of the grid residual to its
  noise floor, the residual of the same grid frames detected with settings derived by
  hand from the truth (:mod:`tests.synth.truth_params`);
- ``rods_min``: fewest rod markers any camera's DLT used (of 24);
- ``recall3_pct`` and ``ghost_pct``: walk01's 3D points against the true markers seen by
  three cameras or more, and the share of points near no true marker;
- ``labelled``, ``switches``: walk01's trajectories named right, of the true markers;
- ``stick_mae_mm`` and ``g_err_pct``: the stick length error and the thrown marker's g.

Detection recall, precision and centroid RMS on isolated markers are scored per image by
:mod:`tests.detect.presets_acceptance` with the same derivation.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from kisscal import session
from kisscal.grid import GridParams, linearise_frames
from kisscal.synth.plan import plan_session, render_grid, render_trial
from kisscal.synth.presets import synth_options
from kisscal.synth.truth import camera_detection_truth
from tests.recon.subsets import found_and_ghosts, true_markers
from tests.synth.rig_check import trial_ranges
from tests.synth.truth_params import detection_params


def grid_floor_px(preset: str, seed: int) -> list[float]:
    """Each camera's grid residual with detection settings derived by hand from truth."""
    plan = plan_session(synth_options(preset, seed, fields=10))
    floors = []
    for ci in range(len(plan.rig)):
        shots = list(render_trial(plan, "walk01", ci))[:4]
        truth = camera_detection_truth(plan, ci, trial_ranges([t for _, _, t in shots]))
        params, _ = detection_params(truth, "grid", plan.render.blur_px)
        grid = linearise_frames(render_grid(plan, ci)[0], GridParams(), params)
        floors.append(float(grid.linearisation.quality.residual_rms_after_px))
    return floors


def recall_and_ghosts(root: Path, trial: str = "walk01") -> tuple[float, float]:
    """Recall of the true markers seen by >= 3 cameras and the ghost share of ``trial``."""
    from kisscal.io.points3d import read_points3d

    xyz, seen = true_markers(root, trial)
    pts = read_points3d(root / "out" / "trials" / trial / "points3d.csv")
    found, ghosts = found_and_ghosts(pts.field, pts.xyz_mm, xyz)
    seen3 = seen >= 3
    return float((found & seen3).sum() / max(seen3.sum(), 1)), ghosts / max(len(pts.field), 1)


def measure(preset: str, seed: int, work: Path, fields: int | None) -> dict[str, Any]:
    """Synthesise, run and score one session (see module)."""
    root = work / f"{preset}{seed}"
    session.synthesise(root, preset=preset, seed=seed, fields=fields, walking5=False, force=True)
    t0 = time.perf_counter()
    summary = session.run(root)
    run_s = time.perf_counter() - t0
    cams = summary["cameras"]
    floors = grid_floor_px(preset, seed)
    ratios = [cams[c]["grid"]["rms_px"] / f for c, f in zip(cams, floors, strict=True)]
    rods = [json.loads((root / "out" / "dlt" / f"{c}.json").read_text())["n_points"] for c in cams]
    truth = session.evaluate(root)
    walk = truth["walk01"]
    recall, ghosts = recall_and_ghosts(root)
    return {
        "rig": f"{preset}:{seed}",
        "cameras": len(cams),
        "dots_min": min(cams[c]["grid"]["dots_used"] for c in cams),
        "grid_rms_px_max": round(max(cams[c]["grid"]["rms_px"] for c in cams), 4),
        "grid_ratio_max": round(max(ratios), 2),
        "rods_min": min(rods),
        "recall3_pct": round(100 * recall, 2),
        "ghost_pct": round(100 * ghosts, 2),
        "labelled": f"{walk['correctly_labelled']}/{walk['n_true_markers']}",
        "switches": walk["identity_switches"],
        "stick_mae_mm": round(truth["stick"]["stick_length"]["mean_abs_error_mm"], 3),
        "g_err_pct": round(100 * truth["throw"]["gravity"]["relative_error"], 3),
        "run_s": round(run_s),
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rigs", nargs="+", help="PRESET:SEED, e.g. modern:31")
    parser.add_argument("--work", type=Path, default=Path("presets-acceptance"))
    parser.add_argument("--fields", type=int, default=None, help="walk fields (preset's own)")
    args = parser.parse_args(argv)
    for rig in args.rigs:
        preset, seed = rig.split(":")
        try:
            line = measure(preset, int(seed), args.work, args.fields)
        except Exception as exc:  # report the rig and go on with the others
            line = {"rig": rig, "failed": f"{type(exc).__name__}: {exc}"}
        print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
