"""Measure issue 5's "done when" numbers on the synthetic rig (not a test; run it):

    python -m tests.tracking.measure            # table over seeds and two scenarios
    python -m tests.tracking.measure --sweep out.csv   # also the PNC x MNC table

Scenario "synth walk01": the gait trial ``kisscal synth`` makes (15 markers, walking
3.4 m through the volume), here with 300 fields. Scenario "out of view": the same walker
at about 1.2 m/s (7 m in 300 fields), so it walks into and out of the cameras' views and
markers flicker at the edges. Points: true positions + 0.5 mm noise per axis, kept where
at least two of the six cameras see the marker (geometric occlusion by the body), plus
about one ghost point per field living 1-4 fields.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from kisscal.io.trajectories import write_sweep_csv
from kisscal.tracking import TrackingParams, build_trajectories, sweep_noise
from tests.tracking._eval import score
from tests.tracking._rig import rig_gait

SCENARIOS = {"synth walk01": 3400.0, "out of view": 7000.0}


def run(seeds=range(1, 9), n_fields: int = 300) -> list[str]:
    lines = [
        "scenario      seed tracks_raw blended final one/marker labels_ok switches "
        "cover_vis cover_span rmse_meas rmse_fill unnamed  s",
    ]
    for scenario, path in SCENARIOS.items():
        for seed in seeds:
            r = rig_gait(seed, n_fields, path_mm=path, ghosts_per_field=1.0)
            t0 = time.perf_counter()
            res = build_trajectories(
                r.field, r.xyz_mm, TrackingParams(), r.names, r.template_mm, r.segments
            )
            dt = time.perf_counter() - t0
            s = score(res, r.truth, r.visible, r.names)
            named = s.n_tracks - len(res.labelling.unlabelled)
            lines.append(
                f"{scenario:<13s} {seed:4d} {res.n_pieces:10d} {res.n_pieces_blended:7d} "
                f"{s.n_tracks:5d} {named == 15 and s.one_per_marker!s:>10s} "
                f"{s.labels_correct:5d}/{named:<3d} {s.identity_switches:8d} "
                f"{s.coverage_visible:9.4f} {s.coverage:10.4f} {s.rmse_measured_mm:9.2f} "
                f"{s.rmse_filled_mm:9.2f} {len(res.labelling.unlabelled):7d} {dt:5.2f}"
            )
    return lines


def sweep(path: str, seed: int = 1, n_fields: int = 300) -> str:
    """The thesis' PNC x MNC table on the out-of-view scenario (where tracks coast)."""
    r = rig_gait(seed, n_fields, path_mm=7000.0, ghosts_per_field=1.0)
    rows = sweep_noise(r.field, r.xyz_mm, r.segments, names=r.names, template_mm=r.template_mm)
    write_sweep_csv(path, rows)
    out = [f"wrote {path}"]
    for row in rows:
        stats = {(s.segment, s.kind): s for s in row.segments}
        for seg in (("RKNE", "RANK"), ("LKNE", "LANK")):
            m, c = stats.get((seg, "measured")), stats.get((seg, "corrected"))
            if m and c:
                out.append(
                    f"PNC {row.pnc:<6} MNC {row.mnc:<6} {seg[0]}-{seg[1]} mean "
                    f"{m.mean_mm:7.2f}/{c.mean_mm:7.2f} var {m.variance_mm2:6.3f}/"
                    f"{c.variance_mm2:6.3f} SD {m.sd_mm:5.3f}/{c.sd_mm:5.3f} SD/mean "
                    f"{m.sd_over_mean:.5f}/{c.sd_over_mean:.5f} (measured/corrected)"
                )
        out.append(
            f"PNC {row.pnc:<6} MNC {row.mnc:<6} missing-point predictions: "
            + " ".join(f"{k}={v}" for k, v in sorted(row.predictions.items()))
        )
    return "\n".join(out)


if __name__ == "__main__":
    np.set_printoptions(linewidth=160)
    print("\n".join(run()))
    if len(sys.argv) > 2 and sys.argv[1] == "--sweep":
        print(sweep(sys.argv[2]))
