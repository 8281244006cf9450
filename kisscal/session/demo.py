"""``kisscal demo``: synthesise a KISS-like session, process it, print what a user checks."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from kisscal._text import plural
from kisscal.io.files import write_json
from kisscal.io.store import SessionStore
from kisscal.io.summary import CameraFigures, RigCheck, TrialFigures
from kisscal.session.report import report
from kisscal.session.run import run
from kisscal.session.synth import evaluate, synthesise

Echo = Callable[[str], object]


def demo(out: Path, *, seed: int = 1, echo: Echo = lambda _: None) -> dict[str, Any]:
    """``kisscal demo``: synthesise a KISS-like session into ``out``, run it, print figures.

    The printed figures are the ones written to ``out/out/summary.json`` (``truth`` holds
    the comparison with the synthetic ground truth).
    """
    out = Path(out)
    t0 = time.perf_counter()
    if (out / "session.toml").is_file():
        echo(f"using the existing session in {out}")
    else:
        # walk5 cut to the fields the KISS rig sees whole: a first run warns of nothing
        synthesise(out, seed=seed, echo=echo, replay_in_view=True)
    summary = run(out, echo=echo)
    summary["truth"] = evaluate(out)
    summary["timings"]["total_s"] = round(time.perf_counter() - t0, 1)
    summary_path = SessionStore(out).summary_path
    write_json(summary_path, summary)
    try:
        report_path: Path | None = report(out)
    except Exception as exc:  # the figures are a convenience; the numbers are already written
        echo(f"report not written: {exc}")
        report_path = None
    _print_summary(summary, echo)
    echo(f"summary: {summary_path}")
    if report_path is not None:
        echo(f"report:  {report_path}")
    return summary


def _print_summary(summary: dict[str, Any], echo: Echo) -> None:
    echo("")
    echo(f"kisscal demo: {summary['session']} ({summary['timings']['total_s']} s)")
    echo(f"{'camera':<8}{'grid rms px':>12}{'DLT rms px':>12}")
    for cam in summary["cameras"]:
        f = CameraFigures.read(summary, cam)
        echo(f"{cam:<8}{f.grid_rms_px:>12.3f}{f.dlt_rms_px:>12.3f}")
    if summary.get("rods"):
        rig = RigCheck.read(summary)
        echo(
            f"rod markers, 3D error in-sample {rig.in_sample_mean_mm:.3f} mm, "
            f"leave-one-rod-out {rig.leave_one_rod_out_mean_mm:.3f} mm"
        )
    for trial, t in summary["truth"].items():
        echo(_trial_line(trial, t, TrialFigures.read(summary, trial).fits_marker_set))


def _trial_line(trial: str, t: dict[str, Any], labelled: bool) -> str:
    """One trial's figures against its truth; labels only where a marker set named them."""
    parts = [
        f"{trial}: {plural(t['n_trajectories'], 'trajectory')} for "
        f"{plural(t['n_true_markers'], 'marker')}"
    ]
    if labelled:
        parts.append(f"{t['correctly_labelled']} labelled right")
    rmse = f"3D RMSE {t['rmse_measured_mm']:.2f} mm"
    if np.isfinite(t["rmse_filled_mm"]):
        rmse += f" (filled {t['rmse_filled_mm']:.2f} mm)"
    parts += [rmse, f"coverage {100 * t['coverage']:.1f} %"]
    line = ", ".join(parts)
    if "stick_length" in t:
        sl = t["stick_length"]
        line += f"; stick length error {sl['mean_abs_error_mm']:.2f} +/- {sl['sd_mm']:.2f} mm"
    if "gravity" in t:
        line += f"; g = {t['gravity']['g_m_s2']:.3f} m/s^2"
    return line
