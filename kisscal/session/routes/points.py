"""Control points given per camera (``[calibration] points``): one DLT each.

For a lab whose calibration object is not the seeds' rods: a frame of known markers or a
digitised target, given as ``u_px,v_px,x_mm,y_mm,z_mm`` rows per camera (raw pixels).
Unless a DLT switch is given, the camera model is chosen by held-out points
(:mod:`kisscal.dlt.select`): the points, matched across cameras by their lab position,
are dealt into ``model_folds`` subsets and each left out in turn.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from kisscal.dlt import calibrate_camera
from kisscal.dlt.select import (
    MODELS,
    CameraPoints,
    ModelChoice,
    choose_model,
    interleaved_folds,
)
from kisscal.errors import InputError
from kisscal.grid import apply_linearisation
from kisscal.io.dltfiles import read_control_points_csv, write_dlt_json
from kisscal.session.routes import RouteInputs, write_check


def calibrate_from_points(inputs: RouteInputs) -> dict[str, Any]:
    """Every camera's DLT from its control-point file (the model chosen by held-out points)."""
    config = inputs.config
    if config.calibration is None:
        raise InputError(f"{config.path}: the points route needs [calibration] points")
    read = {}
    for cam in inputs.cameras:
        path = config.root / config.calibration.points.replace("{camera}", cam.id)
        uv_raw, xyz, labels = read_control_points_csv(path)
        uv = apply_linearisation(inputs.linearisations[cam.id], uv_raw)
        read[cam.id] = (xyz, uv, labels)
    params = inputs.params.dlt
    choice = None
    if params.selects:
        choice = _choose(read, params)
        params = choice.params(params)
    summary: dict[str, Any] = {}
    for cam_id, (xyz, uv, labels) in read.items():
        res = calibrate_camera(xyz, uv, params, cam_id)
        extra = {"lens_models": choice.camera_dict(cam_id)} if choice is not None else None
        write_dlt_json(
            inputs.store.dlt_path(cam_id), cam_id, res, xyz, uv, labels, extra, kinds="points"
        )
        summary[cam_id] = res
        inputs.echo(
            f"  calibrate {cam_id}: {res.method}, {len(xyz)} control points, "
            f"rms {res.rms_px:.3f} px"
        )
    if choice is not None:
        _say_choice(inputs, choice)
        if inputs.whole_rig and np.isfinite(choice.held_out_3d_mm[choice.chosen]):
            check = _check(choice)
            write_check(inputs, check)
            summary["_check"] = check
    return summary


def _choose(
    read: dict[str, tuple], params: Any, candidates: Sequence[str] = tuple(MODELS)
) -> ModelChoice:
    """Points matched across cameras by their lab position, dealt into folds."""
    every = np.concatenate([xyz for xyz, _, _ in read.values()])
    _, ids = np.unique(np.round(every, 6), axis=0, return_inverse=True)
    ids = ids.ravel()
    points, start = {}, 0
    for cam, (xyz, uv, _) in read.items():
        points[cam] = CameraPoints(xyz, uv, ids[start : start + len(xyz)])
        start += len(xyz)
    folds = interleaved_folds(np.arange(ids.max() + 1), params.model_folds)
    return choose_model(points, folds, params, candidates)


def _check(choice: ModelChoice) -> dict[str, Any]:
    return {
        "route": "points",
        "held_out_points": choice.points,
        "leave_out_mean_mm": choice.held_out_3d_mean_mm[choice.chosen],
        "leave_out_max_mm": choice.held_out_3d_max_mm[choice.chosen],
        "leave_out_rms_mm": choice.held_out_3d_mm[choice.chosen],
        "lens_models": choice.rig_dict(),
    }


def _say_choice(inputs: RouteInputs, choice: ModelChoice) -> None:
    figures = ", ".join(
        f"{m} {v:.3f} mm" if np.isfinite(v) else f"{m} -" for m, v in choice.held_out_3d_mm.items()
    )
    inputs.echo(
        f"  camera model: {choice.chosen}, by {choice.by} over {choice.folds} subsets ({figures})"
    )
