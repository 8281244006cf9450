"""The seeds' route: rods recognised in every camera's rod frames, one DLT each.

Küçük (2005, 2.3) and Shafiq et al. (2001, 4): four rods of six surveyed markers hang in the
volume; each camera's DLT is solved from the 24 markers it recognises (optionally MDLT,
Kolahi et al. 2007, or refined in pixels), and the leave-one-rod-out test measures how well
the calibration extrapolates.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from kisscal.dlt import calibrate_rods, make_rods
from kisscal.dlt.params import Rod
from kisscal.dlt.rig import RodCalibration
from kisscal.errors import InputError
from kisscal.grid import apply_linearisation
from kisscal.io.dltfiles import write_dlt_outputs
from kisscal.io.files import write_json
from kisscal.io.frames import source_files
from kisscal.report.dlt import CameraResiduals, residual_figure, rig_figure
from kisscal.session.inputs import figure
from kisscal.session.progress import Echo
from kisscal.session.routes import RouteInputs, frame_files, marker_detection, static_blobs
from kisscal.session.routes.trial_bundle import (
    has_files,
    image_trials,
    lens_from_trials,
    trials_key,
    uses_trials,
)
from kisscal.session.runner import run_keyed


def calibrate_from_rods(inputs: RouteInputs) -> dict[str, Any]:
    """Every camera's DLT from its rod frames; the leave-one-rod-out check for the rig.

    Returns ``{camera: DltResult}`` plus the rig check under ``"_check"`` (whole rig only).
    """
    config, params = inputs.config, inputs.params
    if config.rods is None:
        raise InputError(f"{config.path}: the rods route needs a [rods] table")
    store = inputs.store
    rods = make_rods([(r.name, r.points_mm) for r in config.rods.rods])
    rod_frames = frame_files(inputs, config.rods.images, "rod", config.rods.fields)
    lins = inputs.linearisations
    detection = marker_detection(inputs)

    def compute() -> dict[str, Any]:
        blobs = static_blobs(inputs, rod_frames, "rods", config.rods.fields, detection)
        blobs_px = {c: [apply_linearisation(lins[c], uv) for uv in f] for c, f in blobs.items()}
        t0 = time.perf_counter()
        cal = calibrate_rods(blobs_px, rods, params.dlt, leave_one_out=inputs.whole_rig)
        if uses_trials(inputs):
            cal = lens_from_trials(inputs, blobs_px, rods, cal)[0]
        write_dlt_outputs(cal, store.dlt_path, store.dltdv_path)
        rig = {k: v for k, v in cal.summary().items() if k != "cameras"}
        summary: dict[str, Any] = dict(cal.results)
        if inputs.whole_rig:
            write_json(store.calibration_file("check"), rig)
            summary["_check"] = rig
        _say_rods(inputs.echo, cal, rig, time.perf_counter() - t0)
        _rod_figures(inputs, cal, rods)
        return summary

    def cached() -> dict[str, Any]:
        inputs.echo("  calibrate: cached (rod images, linearisation and parameters unchanged)")
        return {"_check": store.calibration_doc("check")}

    if not inputs.whole_rig:  # the rig's check is the output the key is kept beside
        return compute()
    lost = _lost_trials(inputs)
    if lost and store.calibration_file("check").is_file():
        inputs.echo(
            f"  calibrate: trial {', '.join(lost)}, which the rods were adjusted with, has "
            "no images now; the calibration made with it is kept (--refresh redoes it)"
        )
        return cached()
    stage = (
        "calibrate",
        {c: source_files(f) for c, f in rod_frames.items()},
        config.rods.fields,
        {c: lins[c] for c in rod_frames},
        detection,
        params.dlt,
        [(r.name, r.points_mm) for r in config.rods.rods],
        trials_key(inputs),
    )
    return run_keyed(store, store.calibration_file("check"), stage, cached, compute)


def _lost_trials(inputs: RouteInputs) -> list[str]:
    """The trials the rods are adjusted with that have lost their files."""
    if not uses_trials(inputs):
        return []
    return [t.name for t in image_trials(inputs) if not has_files(inputs.config, t)]


def _say_rods(echo: Echo, cal: RodCalibration, rig: dict[str, Any], seconds: float) -> None:
    for cam_id, res in cal.results.items():
        missing = cal.matches[cam_id].missing
        echo(
            f"  calibrate {cam_id}: {res.method}, {len(res.residuals_px)} rod markers, "
            f"rms {res.rms_px:.3f} px, centre {np.round(res.centre_mm).tolist()} mm"
            + (f", missing {', '.join(missing)}" if missing else "")
        )
    if "rods_in_sample_mean_mm" in rig:
        loo = rig.get("leave_one_rod_out", {})
        echo(
            f"  rods reconstructed in-sample: mean {rig['rods_in_sample_mean_mm']:.3f} mm"
            + (f"; leave-one-rod-out mean {loo['mean_mm']:.3f} mm" if loo else "")
            + f" ({seconds:.1f} s)"
        )


def _rod_figures(inputs: RouteInputs, cal: RodCalibration, rods: tuple[Rod, ...]) -> None:
    sizes = {c.id: c.size_px for c in inputs.config.cameras}
    residuals = {
        c: CameraResiduals(cal.control_uv_px[c], r.residuals_px, sizes[c], r.rms_px)
        for c, r in cal.results.items()
    }
    figure(inputs.root, "dlt_residuals", residual_figure, residuals)
    figure(
        inputs.root,
        "rig",
        rig_figure,
        {c: r.centre_mm for c, r in cal.results.items()},
        [(r.name, r.points_mm) for r in rods],
        {c: r.R for c, r in cal.results.items()},
    )
