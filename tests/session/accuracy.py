"""End-to-end accuracy table of the whole pipeline on rendered synthetic sessions.

``python -m tests.session.accuracy 1 2 3`` synthesises a session per seed (250-field gait
trial) under ``$TMPDIR/kisscal-accuracy``, runs ``kisscal run`` on it and prints one JSON
line of figures per seed, scored against the session's truth.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

from kisscal import session


def figures(seed: int, base: Path, fields: int = 250) -> dict:
    root = base / f"s{seed}"
    if not (root / "session.toml").exists():
        session.synthesise(root, seed=seed, fields=fields)
    t0 = time.perf_counter()
    summary = session.run(root)
    elapsed = time.perf_counter() - t0
    ev = session.evaluate(root)
    walk, stick, throw = ev["walk01"], ev["stick"]["stick_length"], ev["throw"]["gravity"]
    cams = summary["cameras"].values()
    return {
        "seed": seed,
        "run_s": round(elapsed, 1),
        "grid_rms_px_max": round(max(c["grid"]["rms_px"] for c in cams), 4),
        "dlt_rms_px_max": round(max(c["dlt"]["rms_px"] for c in cams), 4),
        "rods_in_sample_mm": round(summary["rods"]["rods_in_sample_mean_mm"], 3),
        "rods_leave_one_out_mm": round(summary["rods"]["leave_one_rod_out"]["mean_mm"], 3),
        "walk_trajectories": walk["n_trajectories"],
        "walk_labelled_right": walk["correctly_labelled"],
        "walk_switches": walk["identity_switches"],
        "walk_rmse_mm": round(walk["rmse_measured_mm"], 3),
        "walk_filled_rmse_mm": round(walk["rmse_filled_mm"], 3),
        "walk_coverage": round(walk["coverage"], 4),
        "stick_mae_mm": round(stick["mean_abs_error_mm"], 3),
        "stick_sd_mm": round(stick["sd_mm"], 3),
        "g_m_s2": round(throw["g_m_s2"], 4),
    }


if __name__ == "__main__":
    base = Path(tempfile.gettempdir()) / "kisscal-accuracy"
    for seed in [int(s) for s in sys.argv[1:]] or [1, 2, 3]:
        print(json.dumps(figures(seed, base)), flush=True)
