"""Any known target (``[calibration] target``): matched automatically from clicked seeds.

For each camera the target's dots are found in its photographs
(:mod:`kisscal.target.dots`), every target point is matched to a dot starting from the
four or more points the user clicked (:mod:`kisscal.target.match`), and the camera is
fitted to every match with the terms (principal point, pixel aspect, Brown lens terms)
that lower the held-out reprojection error (:mod:`kisscal.target.resect`). Writes the
version-1 files (method ``target``), ``dlt/target.json`` (matched and unmatched points
and the camera models compared, per camera) and ``dlt/check.json`` (every
``holdout_step``-th matched point left out of the fits and reconstructed from all
cameras).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from kisscal.bundle.frame import average_static
from kisscal.dlt.triangulate import triangulate_observations
from kisscal.errors import EstimationFailed, InputError
from kisscal.grid import apply_linearisation
from kisscal.io.dltfiles import read_control_points_csv
from kisscal.io.files import read_table, write_json
from kisscal.io.frames import source_files
from kisscal.report.dlt import CameraResiduals, residual_figure
from kisscal.session.inputs import figure
from kisscal.session.routes import RouteInputs, frame_files, outputs_of, write_check
from kisscal.session.routes.lens_files import write_lens_camera, written_dlt
from kisscal.session.runner import run_keyed
from kisscal.target.dots import find_target_dots
from kisscal.target.match import TargetMatch, fit_camera, match_target
from kisscal.target.one_plane import unmatched_beside_one_plane
from kisscal.target.resect import model_name
from kisscal.target.seeds import clicked

ROUTE = "target"
TARGET_COLUMNS = ("x_mm", "y_mm", "z_mm")


def calibrate_from_target(inputs: RouteInputs) -> dict[str, Any]:
    """Every camera from its photographs of the target and its clicked seeds."""
    config = inputs.config
    cal = config.calibration
    if cal is None or not (cal.target and cal.images and cal.seeds):
        raise InputError(
            f"{config.path}: the target route needs [calibration] target, images and seeds"
        )
    target_path = config.root / cal.target
    table = read_table(target_path, required=TARGET_COLUMNS, numeric=TARGET_COLUMNS)
    target = np.column_stack([table[c] for c in TARGET_COLUMNS]).astype(float)
    frames = frame_files(inputs, cal.images, "calibration", cal.fields)
    seed_paths = {c.id: config.root / cal.seeds.replace("{camera}", c.id) for c in inputs.cameras}
    store = inputs.store
    target_json = store.calibration_file("target")

    def compute() -> dict[str, Any]:
        t0 = time.perf_counter()
        matches, dots = {}, {}
        for cam in inputs.cameras:
            lin = inputs.linearisations[cam.id]
            seeds_uv, seeds_xyz, _ = read_control_points_csv(seed_paths[cam.id])
            seeds_uv = _clicked(inputs, cam.id, cam.size_px, seeds_uv, seed_paths[cam.id].name)
            clicks = seeds_uv[np.isfinite(seeds_uv[:, 0])]
            found = [find_target_dots(i, clicks, inputs.params.target) for i in frames[cam.id]]
            dots[cam.id] = apply_linearisation(lin, average_static(found))
            seeds = (apply_linearisation(lin, seeds_uv), seeds_xyz)
            about = (cam.size_px, cam.id, inputs.params.target, inputs.params.dlt)
            matches[cam.id] = match_target(target, *seeds, dots[cam.id], *about)
        doc = _report(matches, time.perf_counter() - t0)
        for cam in inputs.cameras:
            written = _write_camera(inputs, cam, matches[cam.id], dots[cam.id], target)
            doc["cameras"][cam.id]["written_rms_px"] = written
            doc["cameras"][cam.id]["unmatched_beside_one_plane"] = unmatched_beside_one_plane(
                target, dots[cam.id], matches[cam.id].dot, inputs.params.dlt
            )
        check = _held_out(inputs, matches, dots, target) if inputs.whole_rig else {}
        write_json(target_json, doc)
        if inputs.whole_rig:
            write_check(inputs, check)
        _say(inputs, doc, check)
        return {"_check": check}

    def cached() -> dict[str, Any] | None:
        if not outputs_of(inputs, ROUTE):
            return None
        inputs.echo("  calibrate: cached (target, photographs, seeds and parameters unchanged)")
        return {"_check": store.calibration_doc("check")}

    if not inputs.whole_rig:  # the key stands for the whole rig's outputs
        return compute()
    stage = (
        "calibrate-target",
        [target_path, *seed_paths.values()],
        {c: source_files(f) for c, f in frames.items()},
        inputs.linearisations,
        inputs.params.target,
        inputs.params.dlt,
    )
    return run_keyed(store, target_json, stage, cached, compute)


def _clicked(
    inputs: RouteInputs, camera: str, size_px: tuple[int, int], uv: np.ndarray, name: str
) -> np.ndarray:
    """The seeds' pixels, NaN for those that are no clicks (:func:`clicked`), which the
    log names: NaN rather than dropped, so that the matching's messages keep the file's
    line numbers, and no linearisation brings a row back onto the image."""
    off = ~clicked(uv, size_px)
    if off.any():
        lines = ", ".join(str(i + 2) for i in np.flatnonzero(off))
        inputs.echo(
            f"  calibrate {camera}: seed line {lines} of {name} lies outside the "
            f"{size_px[0]} x {size_px[1]} image: left out (not a click)"
        )
    return np.where(off[:, None], np.nan, uv)


def _report(matches: dict[str, TargetMatch], seconds: float) -> dict[str, Any]:
    cams = {}
    for cam, m in matches.items():
        unmatched = np.flatnonzero(m.visible & ~m.matched)
        cams[cam] = {
            "visible": int(m.visible.sum()),
            "matched": int((m.matched & m.visible).sum()),
            "matched_points": np.flatnonzero(m.matched).tolist(),
            "unmatched": unmatched.tolist(),
            "rms_px": m.rms_px,
            "seed_rms_px": m.seed_rms_px,
            "iterations": m.iterations,
            "model": model_name(m.terms),
            "held_out_px": m.held_out_px,
        }
    return {"seconds": round(seconds, 2), "cameras": cams}


def _write_camera(
    inputs: RouteInputs, cfg: Any, m: TargetMatch, dots: np.ndarray, target: np.ndarray
) -> float:
    """The camera's files (:func:`write_lens_camera`) and residual figure; the RMS (px)
    of the calibration as written: the DLT refitted to the matches (on a target that is
    not flat), which may follow them closer than the matching's camera (a tilted sensor,
    as behind a Scheimpflug mount, is a DLT's skew: 0.86 -> 0.11 px on a real one)."""
    k = np.flatnonzero(m.matched)
    uv = dots[m.dot[k]]
    res = uv - m.camera.project(target[k])
    labels = [f"T{i + 1}" for i in k]
    extra = {
        "target": {
            "matched": len(k),
            "visible": int(m.visible.sum()),
            "model": model_name(m.terms),
            "held_out_px": m.held_out_px,
        }
    }
    written = write_lens_camera(
        inputs,
        cfg,
        m.camera,
        ROUTE,
        (target[k], uv, res, labels),
        m.iterations,
        extra,
        kinds="target",
    )
    residuals = {cfg.id: CameraResiduals(uv, res, cfg.size_px, m.rms_px)}
    figure(inputs.root, f"target_{cfg.id}", residual_figure, residuals)
    return written


def _held_out(
    inputs: RouteInputs,
    matches: dict[str, TargetMatch],
    dots: dict[str, np.ndarray],
    target: np.ndarray,
) -> dict[str, Any]:
    """Every ``holdout_step``-th matched point: each camera calibrated without them as it
    is written (its lens, then the DLT refitted: :func:`written_dlt`), the points
    reconstructed from all cameras."""
    step = inputs.params.target.holdout_step
    held = np.arange(len(target)) % step == step // 2
    dlts, rows_cam, rows_pt, rows_uv = [], [], [], []
    for c, cfg in enumerate(inputs.cameras):
        m = matches[cfg.id]
        train = m.matched & ~held
        uv = dots[cfg.id][m.dot[train]]
        camera = fit_camera(
            target[train],
            uv,
            cfg.size_px,
            m.camera,
            inputs.params.target,
            m.terms,
            inputs.params.dlt,
        )
        ideal = camera.undistort_px(uv)
        dlts.append(written_dlt(camera, target[train], ideal, inputs.params.dlt, cfg.id))
        test = np.flatnonzero(m.matched & held)
        rows_cam.append(np.full(len(test), c))
        rows_pt.append(test)
        rows_uv.append(camera.undistort_px(dots[cfg.id][m.dot[test]]))
    pts = np.concatenate(rows_pt)
    if len(dlts) < 2 or not len(pts):
        return {"route": ROUTE}
    ids, point = np.unique(pts, return_inverse=True)
    xyz = triangulate_observations(
        np.stack(dlts), point.ravel(), np.concatenate(rows_cam), np.concatenate(rows_uv), len(ids)
    ).xyz_mm
    err = np.linalg.norm(xyz - target[ids], axis=1)
    err = err[np.isfinite(err)]
    if not len(err):
        raise EstimationFailed("target: no held-out target point is seen by two cameras")
    return {
        "route": ROUTE,
        "held_out_points": len(err),
        "leave_out_mean_mm": float(np.mean(err)),
        "leave_out_max_mm": float(np.max(err)),
        "leave_out_rms_mm": float(np.sqrt(np.mean(err**2))),
    }


def _say(inputs: RouteInputs, doc: dict[str, Any], check: dict[str, Any]) -> None:
    for cam, e in doc["cameras"].items():
        inputs.echo(
            f"  calibrate {cam}: target, {e['matched']} of {e['visible']} visible points "
            f"matched (seeds {e['seed_rms_px']:.2f} px), model {e['model']} at "
            f"{e['rms_px']:.3f} px, written as a DLT at {e['written_rms_px']:.3f} px"
        )
        stray = e.get("unmatched_beside_one_plane", 0)
        if 2 * stray >= e["matched"]:
            inputs.echo(
                f"  warning: {cam}: the {e['matched']} points matched all lie in one plane "
                f"of the target, and {stray} dots among their images were not matched: the "
                "camera fits that plane alone and may be wrong off it; click seeds on two "
                "or more levels of the target"
            )
    if "leave_out_mean_mm" in check:
        inputs.echo(
            f"  held-out target points ({check['held_out_points']}): mean 3D error "
            f"{check['leave_out_mean_mm']:.3f} mm, max {check['leave_out_max_mm']:.3f} mm"
        )
