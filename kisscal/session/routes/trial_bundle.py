"""The rods and the session's trials adjusted together (issue 25): inputs of
:func:`kisscal.bundle.points.calibrate_on_points`.

The rods' surveyed markers, as the wand route hands them to its adjustment, and every
image trial's blobs on the grid's linearisation, one table (fields of later trials
numbered after those of earlier ones).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kisscal.bundle.adjust import ControlPoints
from kisscal.bundle.points import POINT, TrialPoints, calibrate_on_points
from kisscal.bundle.quality import leave_control_out
from kisscal.bundle.wand import BlobTable, WandCalibration
from kisscal.camera import Camera
from kisscal.dlt import (
    calibrate_rods,
    correct_lens,
    make_rods,
    reprojection_residuals,
)
from kisscal.dlt.calibrate import dlt_result
from kisscal.dlt.params import DltResult, Rod, RodCheck, rod_markers
from kisscal.dlt.rig import RodCalibration, in_sample_errors
from kisscal.errors import EstimationFailed, InputError, KisscalError
from kisscal.grid import apply_linearisation
from kisscal.io.config import SessionConfig, TrialConfig
from kisscal.session.routes import RouteInputs, frame_files, marker_detection, static_blobs
from kisscal.session.runner import trial_blobs
from kisscal.session.trials import trial_input_files

#: The rods' models the adjustment can start from (a DLT as a pinhole with skew).
PINHOLES = ("dlt", "refined")


def rods_control(
    inputs: RouteInputs,
    blobs_px: Mapping[str, Sequence[NDArray[np.float64]]],
    rods: Sequence[Rod],
    rods_alone: RodCalibration,
) -> tuple[list[Camera], ControlPoints]:
    """Starting cameras (the rods' pinhole choice) and the rods' markers as control points.

    ``blobs_px`` are the rods' linearised blobs and ``rods_alone`` their calibration (the
    rods' own choice of model).
    """
    config, params = inputs.config, inputs.params
    # the adjustment starts from pinholes (L12..L16 could not carry over into it), so
    # from a second fit without them when the rods chose them (its cameras only: no
    # leave-one-rod-out, the adjustment's own is the check)
    rod_cal = rods_alone
    if rods_alone.models is not None and rods_alone.models.chosen not in PINHOLES:
        rod_cal = calibrate_rods(blobs_px, rods, params.dlt, False, PINHOLES)
    cams, xyz, uv, group = [], [], [], []
    for c, cam in enumerate(config.camera_ids):
        muv = rod_cal.marker_uv_px[cam]  # (rods, markers, 2)
        for g, rod in enumerate(rods):
            seen = np.isfinite(muv[g, : len(rod.points_mm)]).all(axis=1)
            cams.append(np.full(int(seen.sum()), c))
            xyz.append(rod.points_mm[seen])
            uv.append(muv[g, : len(rod.points_mm)][seen])
            group.append(np.full(int(seen.sum()), g))
    control = ControlPoints(
        np.concatenate(cams).astype(np.int64),
        np.concatenate(xyz),
        np.concatenate(uv),
        np.concatenate(group).astype(np.int64),
    )
    start = [Camera.from_dlt(rod_cal.results[c].L) for c in config.camera_ids]
    return start, control


def rod_blobs(
    inputs: RouteInputs,
) -> tuple[dict[str, list[NDArray[np.float64]]], tuple[Rod, ...]]:
    """The rods' blobs of every camera on the grid's linearisation, and the rods."""
    config, lins = inputs.config, inputs.linearisations
    rods = make_rods([(r.name, r.points_mm) for r in config.rods.rods])
    fields = config.rods.fields
    frames = frame_files(inputs, config.rods.images, "rod", fields)
    found = static_blobs(inputs, frames, "rods", fields, marker_detection(inputs))
    blobs = {cam: [apply_linearisation(lins[cam], uv) for uv in f] for cam, f in found.items()}
    return blobs, rods


def trials_table(inputs: RouteInputs) -> BlobTable:
    """Every image or video trial's blobs (not the wand's), grid-linearised, one table
    (the fields of each trial after those of the one before)."""
    config = inputs.config
    per_camera: list[list] = [[] for _ in config.cameras]
    detection = marker_detection(inputs)
    for trial in image_trials(inputs):
        try:
            blobs = trial_blobs(config, trial, detection, inputs.echo, inputs.workers, inputs.ahead)
        except KisscalError as exc:  # the trial fails on its own later, as without the bundle
            inputs.echo(f"  calibrate: trial {trial.name!r} left out of the adjustment: {exc}")
            continue
        for c, cam in enumerate(config.cameras):
            lin = inputs.linearisations[cam.id]
            per_camera[c].extend(apply_linearisation(lin, uv) for uv in blobs[cam.id])
    return BlobTable.of(per_camera)


def trials_key(inputs: RouteInputs) -> list:
    """What a calibration adjusted with the trials is keyed on besides its own inputs:
    the trials' files and the wand settings, when :func:`uses_trials`."""
    if not uses_trials(inputs):
        return []
    listed = (_input_files(inputs.config, t) for t in image_trials(inputs))
    return [[files for files in listed if files is not None], inputs.params.wand]


def uses_trials(inputs: RouteInputs) -> bool:
    """Whether the rods route adjusts the rods and the trials together: the whole rig,
    three rods or more (to leave one out), the model left to the data (``[dlt]
    trials_bundle``, no model switch) and a trial of images or video besides the wand's."""
    dlt = inputs.params.dlt
    rods = inputs.config.rods  # none on the wand route with an axes object
    enough = inputs.whole_rig and rods is not None and len(rods.rods) >= 3
    return enough and dlt.trials_bundle and dlt.selects and bool(image_trials(inputs))


def image_trials(inputs: RouteInputs) -> list[TrialConfig]:
    """The trials the rods are adjusted with: those ``[dlt] bundle_trials`` names, or
    (none named) the session's image and video trials but the wand's."""
    config = inputs.config
    usable = usable_trials(config)
    named = inputs.params.dlt.bundle_trials
    unknown = [n for n in named if n not in usable]
    if unknown:
        raise InputError(
            f"{config.path}: [dlt] bundle_trials names {', '.join(unknown)}, not an image "
            f"or video trial of the session (those: {', '.join(usable) or 'none'})"
        )
    if named:
        return [usable[n] for n in named]
    return [t for t in usable.values() if has_files(config, t)]


def has_files(config: SessionConfig, trial: TrialConfig) -> bool:
    """Whether every camera of ``trial`` has its files: a trial without them is left to
    fail on its own, not to fail the calibration of the session's other trials."""
    return _input_files(config, trial) is not None


def _input_files(config: SessionConfig, trial: TrialConfig) -> dict[str, list[Path]] | None:
    """:func:`~kisscal.session.trials.trial_input_files` of ``trial``, or None when a
    camera lacks its files (listed once: a trial's listing is thousands of files)."""
    try:
        return trial_input_files(config, trial)
    except KisscalError:
        return None


def usable_trials(config: SessionConfig) -> dict[str, TrialConfig]:
    """The session's trials the rods can be adjusted with, by name: its image and video
    trials but the wand's."""
    wand = config.wand.trial if config.wand is not None else None
    return {t.name: t for t in config.trials if t.name != wand and t.source in ("images", "video")}


def lens_from_trials(
    inputs: RouteInputs,
    blobs_px: Mapping[str, Sequence[NDArray[np.float64]]],
    rods: Sequence[Rod],
    rods_alone: RodCalibration,
) -> tuple[RodCalibration, WandCalibration | None]:
    """The rods' calibration with each camera replaced by the rods and trials adjusted
    together (:func:`kisscal.bundle.points.calibrate_on_points`), and that adjustment;
    the rods' own (and None) when the trials hold too few markers seen by three cameras.

    The adjustment is the wand route's on a grid (``[wand]`` lens terms, those beyond the
    first where the trials' markers show them, cameras resected as DLTs with
    ``resect_terms`` of Kolahi's terms), the rods weighed ``[dlt] bundle_rods_weight``
    times their estimated noise ratio: one adjustment, and its
    leave-one-rod-out for the check. That leave-one-rod-out does not judge it: the left-out
    rods' markers disagreed with the volume's truth in sign (issue 25: on the four-camera
    seed-7 rig -2.6 standard errors against the rods' own model, for a volume error 3.5
    times lower).
    """
    # the rods' pinhole fit first: it runs while the trials' images are still detected in
    # the background (inputs.ahead, kisscal.session.ahead), which the trials' table then waits for
    start, control = rods_control(inputs, blobs_px, rods, rods_alone)
    return adjusted_with_trials(inputs, trials_table(inputs), start, control, rods, rods_alone)


def adjusted_with_trials(
    inputs: RouteInputs,
    table: BlobTable,
    start: Sequence[Camera],
    control: ControlPoints,
    rods: Sequence[Rod],
    rods_alone: RodCalibration,
    markers: TrialPoints | None = None,
) -> tuple[RodCalibration, WandCalibration | None]:
    """:func:`lens_from_trials` from the trials' table and the rods' pinholes and control
    points (:func:`trials_table`, :func:`rods_control`) already made, and the trials'
    markers (:func:`kisscal.bundle.points.trial_points`) when the caller needs them too."""
    params = inputs.params
    bundle = params.wand.on_grid()
    sizes = [c.size_px for c in inputs.config.cameras]
    weight = params.dlt.bundle_rods_weight
    try:
        cal = calibrate_on_points(
            table, start, control, sizes, bundle, params.dlt, 3, weight, markers
        )
    except EstimationFailed as exc:
        inputs.echo(f"  calibrate: {exc}; the rods' own model kept")
        return rods_alone, None
    weighed = cal.refit_params(replace(bundle, control_weight=cal.control.weight))
    terms = weighed.lens_terms
    check = _rod_check(leave_control_out(cal, POINT, cal.control.group, weighed), rods)
    names = ", ".join(t.name for t in image_trials(inputs))
    inputs.echo(
        f"  calibrate: rods and trials ({names}) adjusted together ({len(cal.fields)} "
        f"markers, rods weighed {cal.control.weight:.0f} x a marker's image, lens terms "
        f"{', '.join(terms) or 'none'}): "
        f"leave-one-rod-out mean {check.overall_mean_mm:.3f} mm, the rods' alone "
        f"{rods_alone.check.overall_mean_mm:.3f} mm"
    )
    ids = inputs.config.camera_ids
    results = {c: _result(rods_alone, c, cam) for c, cam in zip(ids, cal.written, strict=True)}
    models = rods_alone.models
    if models is not None:
        models = replace(models, chosen=TRIALS, by=f"rods and trials adjusted together ({names})")
    out = replace(rods_alone, results=results, models=models, check=check)
    in_sample = in_sample_errors(out.results, out.marker_uv_px, rod_markers(rods))
    return replace(out, in_sample_mm=in_sample), cal


#: What ``lens_models`` records as chosen when the trials decided the lens terms.
TRIALS = "trials"


def _result(rods_alone: RodCalibration, cam: str, camera: Camera) -> DltResult:
    """A camera's DLT file content: its rod markers' residuals under ``camera``."""
    L, lens = camera.dlt, camera.kolahi
    xyz, uv = rods_alone.control_xyz_mm[cam], rods_alone.control_uv_px[cam]
    residuals = reprojection_residuals(L, xyz, correct_lens(L, lens, uv))
    return dlt_result(L, "refined", lens, residuals, rods_alone.results[cam].constraint_linear)


def _rod_check(held: tuple[NDArray, NDArray, NDArray], rods: Sequence[Rod]) -> RodCheck:
    """Leave-one-rod-out of the adjustment (:func:`kisscal.bundle.quality.leave_control_out`
    by rod): each rod's markers reconstructed by the cameras adjusted without them."""
    n = max(len(r.points_mm) for r in rods)
    errors = np.full((len(rods), n), np.nan)
    xyz, fold, err = held
    for g, rod in enumerate(rods):
        mine = fold == g
        near = np.linalg.norm(xyz[mine, None] - rod.points_mm[None], axis=2).argmin(axis=1)
        errors[g, near] = err[mine]
    return RodCheck.of(rods, errors)
