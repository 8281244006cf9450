"""``kisscal track``: a trial's 3D points to labelled trajectories and their exports."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.errors import KisscalError
from kisscal.io.config import SessionConfig
from kisscal.io.export import write_c3d, write_trc
from kisscal.io.files import write_json
from kisscal.io.points3d import read_points3d
from kisscal.io.trajectories import write_sweep_csv, write_trajectories_csv
from kisscal.session.inputs import figure, load_config, out_dir, writes_session
from kisscal.session.params import Overrides, stage_params
from kisscal.session.progress import Echo, quiet
from kisscal.tracking import Trajectories, build_trajectories, sweep_noise


@writes_session
def track(
    root: Path,
    trial_name: str,
    overrides: Overrides | None = None,
    sweep: bool = False,
    echo: Echo = quiet,
) -> Trajectories:
    """``kisscal track``: labelled trajectories of a trial from its ``points3d.csv``.

    Writes ``trajectories.csv``, ``.c3d`` and ``.trc``; with ``sweep``, also the thesis'
    PNC x MNC segment-length table as ``sweep.csv``.
    """
    root = Path(root)
    config = load_config(root)
    trial = config.trial(trial_name)
    params = stage_params(config, overrides)
    tdir = out_dir(root) / "trials" / trial.name
    points_path = tdir / "points3d.csv"
    if not points_path.is_file():
        raise KisscalError(
            f"{points_path}: missing; run `kisscal reconstruct {root} {trial.name}` first"
        )
    pts = read_points3d(points_path)
    names, template, segments = _marker_set(config)
    t0 = time.perf_counter()
    result = build_trajectories(pts.field, pts.xyz_mm, params.tracking, names, template, segments)
    # a trial without markers still gets its files: header only, frames without points
    frames = None if len(result.tracks.field) else _trial_fields(tdir, pts.field)
    write_trajectories_csv(tdir / "trajectories.csv", result.tracks, result.labels)
    write_c3d(tdir / "trajectories.c3d", result.tracks, result.labels, config.rate_hz, frames)
    write_trc(tdir / "trajectories.trc", result.tracks, result.labels, config.rate_hz, frames)
    write_json(tdir / "tracking.json", _tracking_summary(result))
    figure(
        root,
        f"trajectories_{trial.name}",
        "kisscal.report.tracking",
        "trajectories_figure",
        result,
        f"trial {trial.name}: trajectories (mm)",
    )
    figure(
        root,
        f"segments_{trial.name}",
        "kisscal.report.tracking",
        "segment_length_figure",
        result,
        segments,
        config.rate_hz,
    )
    shown = ", ".join(result.labels[:20]) + (" ..." if len(result.labels) > 20 else "")
    echo(
        f"  track {trial.name}: {len(result.labels)} trajectories from {result.n_pieces} pieces "
        f"({shown}) ({time.perf_counter() - t0:.1f} s)"
    )
    if frames is not None:
        echo(f"  warning: {trial.name}: no trajectories; empty files written ({frames} fields)")
    if sweep:
        rows = sweep_noise(pts.field, pts.xyz_mm, segments, params.tracking, names, template)
        write_sweep_csv(tdir / "sweep.csv", rows)
        echo(f"  sweep: {tdir / 'sweep.csv'}")
    return result


def _trial_fields(tdir: Path, field: np.ndarray) -> int:
    """Fields of a trial: from ``recon.json`` (blank fields count), else up to its last
    point, and at least one."""
    recon = tdir / "recon.json"
    known = json.loads(recon.read_text()).get("fields", 0) if recon.is_file() else 0
    return max(int(known), int(field.max(initial=-1)) + 1, 1)


def _marker_set(config: SessionConfig) -> tuple[Any, Any, tuple]:
    """Names, standing template and rigid segments of the session's marker set."""
    if config.markers is None:
        return None, None, ()
    return config.markers.names, config.markers.template_mm, config.markers.segments


def _tracking_summary(result: Trajectories) -> dict[str, Any]:
    lab = result.labelling
    return {
        "pieces": result.n_pieces,
        "pieces_after_blending": result.n_pieces_blended,
        "trajectories": len(result.labels),
        "fits_marker_set": bool(lab.fits_marker_set),
        "unlabelled": list(lab.unlabelled),
        "missing": list(lab.missing),
        "predictions_per_track": dict(
            zip(result.labels, np.asarray(result.n_predicted).tolist(), strict=True)
        ),
    }
