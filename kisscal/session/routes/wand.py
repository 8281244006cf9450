"""A wand waved through the volume (``[wand]``): every camera adjusted together.

On rods (``[wand]`` with ``[rods]``): the rods' calibration on the grid's linearisation
is the start and the rods' surveyed markers stay fixed in the adjustment, which also
estimates each camera's intrinsics, pose and lens terms and every wand pose; with the
session's other trials adjusted with the rods (the rods route's default), their markers
enter the same adjustment and that default is the calibration the wand must not be worse
than (:mod:`.wand_judge`). Alone
(``[wand]`` with ``[axes]``, no grid or rods needed): the cameras start from the wand
images, and the axes object then fixes the lab frame. See :mod:`kisscal.bundle`.

Writes the version-1 files every route writes (``linearisation/<camera>.json``, the
lens terms folded into the 30-coefficient polynomial; ``dlt/<camera>.json`` with method
``wand``), ``dlt/wand.json`` (the figures a technician reads) and ``dlt/check.json``.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np

from kisscal.bundle.adjust import ControlPoints
from kisscal.bundle.frame import average_static
from kisscal.bundle.params import BundleParams
from kisscal.bundle.points import (
    TrialPoints,
    calibrate_on_wand_and_points,
    trial_markers_weight,
    trial_points,
)
from kisscal.bundle.quality import leave_one_group_out
from kisscal.bundle.wand import (
    AxesFrame,
    BlobTable,
    WandCalibration,
    axes_frame,
    calibrate_on_control,
    calibrate_wand_alone,
)
from kisscal.dlt import calibrate_rods
from kisscal.dlt.rig import RodCalibration
from kisscal.errors import InputError
from kisscal.grid import apply_linearisation
from kisscal.io.frames import source_files
from kisscal.session.routes import (
    RouteInputs,
    frame_files,
    marker_detection,
    outputs_of,
    static_blobs,
)
from kisscal.session.routes.trial_bundle import (
    adjusted_with_trials,
    image_trials,
    rod_blobs,
    rods_control,
    trials_key,
    trials_table,
    uses_trials,
)
from kisscal.session.routes.wand_outputs import wand_params, write_wand_outputs
from kisscal.session.runner import run_keyed, trial_blobs
from kisscal.session.trials import trial_input_files


def calibrate_from_wand(inputs: RouteInputs) -> dict[str, Any]:
    """Every camera from the wand trial, on the rods or with the axes object.

    Returns ``{"_check": ...}`` (the leave-out figures) like the rods route.
    """
    config = inputs.config
    if config.wand is None or (config.rods is None and config.axes is None):
        raise InputError(f"{config.path}: the wand route needs [wand] with [rods] or [axes]")
    if not inputs.whole_rig:
        raise InputError(
            "a wand calibration adjusts every camera together; run kisscal calibrate "
            "without --camera"
        )
    store = inputs.store
    wand_json, check_json = store.calibration_file("wand"), store.calibration_file("check")

    def cached() -> dict[str, Any] | None:
        kept = outputs_of(inputs, "wand") or store.calibration_doc("wand").get("kept") == "rods"
        if not (kept and check_json.is_file()):
            return None
        inputs.echo("  calibrate: cached (wand trial, calibration images and parameters unchanged)")
        return {"_check": store.calibration_doc("check")}

    def compute() -> dict[str, Any]:
        t0 = time.perf_counter()
        table = _wand_table(inputs)
        baseline = weighing = None
        if config.rods is not None:
            (cal, rod_check, baseline, weighing), frame = _on_rods(inputs, table), None
        else:
            (cal, frame), rod_check = _with_axes(inputs, table), None
        seconds = time.perf_counter() - t0
        check = write_wand_outputs(inputs, cal, frame, rod_check, seconds, baseline, weighing)
        return {"_check": check}

    return run_keyed(store, wand_json, _stage(inputs), cached, compute)


def _stage(inputs: RouteInputs) -> tuple:
    """What the wand route is keyed on (:func:`~kisscal.session.runner.run_keyed`)."""
    config, params = inputs.config, inputs.params
    trial = config.trial(config.wand.trial)
    objects = []
    if config.rods is not None:
        rods = frame_files(inputs, config.rods.images, "rod", config.rods.fields)
        objects.append({c: source_files(f) for c, f in rods.items()})
        objects.append([(r.name, r.points_mm) for r in config.rods.rods])
    if config.axes is not None:
        axes = frame_files(inputs, config.axes.images, "axes", config.axes.fields)
        objects.append({c: source_files(f) for c, f in axes.items()})
        objects.append(config.axes.points_mm)
    return (
        "calibrate-wand",
        trial_input_files(config, trial),
        objects,
        inputs.linearisations,
        config.wand.markers_mm,
        marker_detection(inputs),
        params.dlt,
        params.recon,
        params.wand,
        trials_key(inputs),
    )


def _wand_table(inputs: RouteInputs) -> BlobTable:
    """The wand trial's blobs, grid-linearised (raw pixels without a grid)."""
    config = inputs.config
    trial = config.trial(config.wand.trial)
    detection = marker_detection(inputs)
    blobs = trial_blobs(config, trial, detection, inputs.echo, inputs.workers, inputs.ahead)
    per_camera = []
    for cam in config.cameras:
        lin = inputs.linearisations[cam.id]
        per_camera.append([apply_linearisation(lin, uv) for uv in blobs[cam.id]])
    return BlobTable.of(per_camera)


def _on_rods(
    inputs: RouteInputs, table: BlobTable
) -> tuple[WandCalibration, RodCalibration, WandCalibration | None, dict | None]:
    """The wand's calibration on the rods, what the rods route would write (kept when the
    wand does not do better) and, when that is the rods and trials adjusted together,
    their adjustment (the judge holds it out as it holds out the wand's) and how the rods
    were weighed (:func:`_with_trials`)."""
    config, params = inputs.config, inputs.params
    blobs, rods = rod_blobs(inputs)
    # what the rods alone give (the rods route's own choice of model); the adjustment
    # starts from their pinholes
    rods_alone = calibrate_rods(blobs, rods, params.dlt, True)
    start, control = rods_control(inputs, blobs, rods, rods_alone)
    ids = config.camera_ids
    inputs.echo(f"  calibrate: wand on the rods' calibration ({len(rods)} rods)")
    wand = wand_params(inputs)
    sizes = [c.size_px for c in config.cameras]
    if uses_trials(inputs):
        # the rods route's default, the rods and trials: the calibration to beat
        trials = trials_table(inputs)
        # the trials' markers reconstructed once, for both adjustments
        markers = trial_points(trials, start, sizes, 3, params.wand.on_grid().max_fields)
        default, baseline = adjusted_with_trials(
            inputs, trials, start, control, rods, rods_alone, markers
        )
        if baseline is not None:
            cal, weighing = _with_trials(inputs, table, trials, start, control, markers, baseline)
            return cal, default, baseline, weighing
    args = (table, start, control, config.wand.markers_mm, sizes, ids, config.wand.trial)
    cal = calibrate_on_control(*args, wand, inputs.params.dlt)
    if wand.control_weight == 0.0 and len(wand.control_weight_factors) > 1:
        cal = _best_weight(inputs, cal, args, wand)
    return cal, rods_alone, None, None


def _with_trials(
    inputs: RouteInputs,
    table: BlobTable,
    trials: BlobTable,
    start: list,
    control: ControlPoints,
    markers: TrialPoints,
    baseline: WandCalibration,
) -> tuple[WandCalibration, dict]:
    """The wand and the session's other trials adjusted together on the rods
    (:func:`kisscal.bundle.points.calibrate_on_wand_and_points`): the trials' markers the
    default calibration adjusts the rods with (:mod:`.trial_bundle`, the same trials), so
    the wand adds to what fixed the lens terms rather than replacing it (issue 25: on the
    four-camera lowcost rig, seed 71, the wand alone on the rods was 10 % worse inside
    the volume than the rods and trials). The rods, the wand's images and the trials'
    markers are weighed by their own noise (Helmert's variance components), starting
    from the rods' weight ``[dlt] bundle_rods_weight`` times their noise ratio. The rods,
    which alone fix the lab frame, are weighed two ways: by their own component, and
    against a trial marker as the rods and trials alone weigh them (``baseline``); the
    one with the lower leave-one-rod-out error is kept (issue 25: the better inside the
    volume on 9 of 12 synthetic rigs, missed by 3-16 %; the held-out wand length picks 8,
    the rods' held-out markers 6: 69-97 % of the squared error inside is the lab frame,
    which only the rods see). Also returns the ``wand.json`` entries naming the weight kept
    (``rods_weighed``) and both weights' figures (``rods_weight_fits``)."""
    config, params = inputs.config, inputs.params
    wand = (config.wand.markers_mm, config.camera_ids, config.wand.trial)
    sizes = [c.size_px for c in config.cameras]
    bundle = wand_params(inputs)
    args = (table, trials, start, control, wand, sizes, bundle, params.dlt)
    fits, figures = {}, {}
    for name, rods_per_point in (("own_noise", 0.0), ("rods_route", baseline.control.weight)):
        how = f"{rods_per_point:.0f} x a trial marker, as without the wand"
        how = how if rods_per_point else "by their own noise"
        cal = calibrate_on_wand_and_points(
            *args, params.dlt.bundle_rods_weight, markers, rods_per_point
        )
        errors = leave_one_group_out(cal, cal.markers(config.wand.markers_mm), bundle)
        loo = float(np.mean(np.concatenate(list(errors.values())))) if errors else np.inf
        inputs.echo(f"  rods weighed {how}: leave-one-rod-out mean {loo:.4f} mm")
        fits[name] = (loo, cal)
        figures[f"{name}_weight"] = float(cal.control.weight)
        figures[f"{name}_leave_one_rod_out_mm"] = loo if np.isfinite(loo) else None
    kept = min(fits, key=lambda k: fits[k][0])  # the first on a tie
    cal = fits[kept][1]
    names = ", ".join(t.name for t in image_trials(inputs))
    inputs.echo(
        f"  calibrate: the wand ({int(np.sum(cal.fields >= 0))} fields) and the trials' "
        f"markers ({names}: {int(np.sum(cal.fields < 0))}) adjusted together, weighed by "
        f"their noise (variance components): a rod marker {cal.control.weight:.0f} x a wand "
        f"image, a trial marker {trial_markers_weight(cal):.1f} x"
    )
    return cal, {"rods_weighed": kept, "rods_weight_fits": figures}


def _best_weight(
    inputs: RouteInputs, cal: WandCalibration, args: tuple, params: BundleParams
) -> WandCalibration:
    """The rods' weight (estimated, times each factor) with the lowest leave-one-rod-out
    error."""
    estimated = cal.control.weight if cal.control is not None else 1.0
    markers = args[3]
    best, best_loo = cal, np.inf
    for factor in params.control_weight_factors:
        weighed = replace(params, control_weight=estimated * factor)
        trial = calibrate_on_control(*args, weighed, inputs.params.dlt)
        errors = leave_one_group_out(trial, markers, params)
        loo = float(np.mean(np.concatenate(list(errors.values())))) if errors else np.inf
        inputs.echo(
            f"  rods weighed {estimated * factor:.0f} x a wand image: leave-one-rod-out "
            f"mean {loo:.3f} mm"
        )
        if loo < best_loo:
            best, best_loo = trial, loo
    return best


def _with_axes(inputs: RouteInputs, table: BlobTable) -> tuple[WandCalibration, AxesFrame]:
    config, params = inputs.config, inputs.params
    ids = config.camera_ids
    sizes = [c.size_px for c in config.cameras]
    inputs.echo("  calibrate: wand alone, the lab frame from the axes object")
    cal = calibrate_wand_alone(
        table, config.wand.markers_mm, sizes, ids, config.wand.trial, params.wand, params.recon
    )
    fields = config.axes.fields
    files = frame_files(inputs, config.axes.images, "axes", fields)
    frames = static_blobs(inputs, files, "axes", fields, marker_detection(inputs))
    blobs = []
    for cam in config.cameras:
        static = average_static(frames[cam.id])
        blobs.append(apply_linearisation(inputs.linearisations[cam.id], static))
    frame = axes_frame(
        cal.cameras, sizes, ids, blobs, config.axes.points_mm, params.wand.length_tol
    )
    return cal, frame
