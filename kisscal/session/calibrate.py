"""``kisscal calibrate``: each camera's DLT, by the route the session describes.

Routes: surveyed rods (:mod:`kisscal.dlt`, the seeds' method) or control points given per
camera (``[calibration] points``). Each writes ``out/dlt/<camera>.json`` and the combined
``out/dlt/dltdv.csv``; everything downstream reads only those.
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.dlt import DltResult, calibrate_camera, calibrate_rods, make_rods
from kisscal.dlt.rig import RodCalibration
from kisscal.errors import KisscalError
from kisscal.grid import Linearisation, apply_linearisation
from kisscal.io.cache import cache_key, is_current, mark_current
from kisscal.io.config import CameraConfig, SessionConfig
from kisscal.io.dltfiles import (
    DltFile,
    read_control_points_csv,
    read_dlt_json,
    write_dlt_json,
    write_dlt_outputs,
    write_dltdv_csv,
)
from kisscal.io.files import write_json
from kisscal.io.frames import camera_frames
from kisscal.session.detection import SizedFrames, detect_frames
from kisscal.session.inputs import (
    figure,
    file_keys,
    linearisation_key,
    load_config,
    out_dir,
    select_cameras,
    writes_session,
)
from kisscal.session.linearise import current_linearisations
from kisscal.session.params import Overrides, StageParams, stage_params
from kisscal.session.progress import Echo, quiet, steps


@writes_session
def calibrate(
    root: Path,
    camera: str | None = None,
    mdlt: bool | None = None,
    refine: bool | None = None,
    lens: bool | None = None,
    overrides: Overrides | None = None,
    echo: Echo = quiet,
    workers: int | None = None,
) -> dict[str, Any]:
    """``kisscal calibrate``: DLT parameters of each camera from rods or control points.

    ``mdlt``, ``refine`` and ``lens`` left as ``None`` keep what the last calibration of
    this session chose (``out/dlt/calibration.json``), so that ``kisscal run`` never
    silently undoes ``kisscal calibrate --mdlt``; ``False`` turns a switch off.

    Writes ``out/dlt/<camera>.json``, ``out/dlt/dltdv.csv`` and ``out/dlt/calibration.json``;
    returns ``{camera: DltResult}`` plus the leave-one-rod-out check under ``"_check"``.
    """
    root = Path(root)
    config = load_config(root)
    o = overrides or Overrides()
    switches = _dlt_switches(root, {"mdlt": mdlt, "refine": refine, "lens": lens}, echo)
    params = stage_params(config, dataclasses.replace(o, dlt={**o.dlt, **switches}))
    lins = current_linearisations(root, echo)
    cameras = select_cameras(config, camera)
    if config.rods is not None:
        whole_rig = camera is None
        summary = _calibrate_rods(root, config, cameras, lins, params, echo, workers, whole_rig)
        route = "rods"
    elif config.calibration is not None and config.calibration.route == "points":
        summary = _calibrate_points(root, config, cameras, lins, params, echo)
        route = "points"
    elif config.calibration is not None:
        raise KisscalError(
            f"{config.path}: [calibration] {config.calibration.route} is not supported by "
            "this version of kisscal"
        )
    else:
        raise KisscalError(
            f"{config.path}: no [rods] and no [calibration]: nothing to calibrate from"
        )
    dlt_dir = out_dir(root) / "dlt"
    all_L = {c: f.L for c, f in read_dlt_files(root, config, required=False).items()}
    write_dltdv_csv(dlt_dir / "dltdv.csv", {c: all_L[c] for c in config.camera_ids if c in all_L})
    write_json(dlt_dir / "calibration.json", {"route": route, "options": switches})
    return summary


_SWITCHES = ("mdlt", "refine", "lens")


def _dlt_switches(root: Path, given: dict[str, bool | None], echo: Echo) -> dict[str, bool]:
    """The DLT switches: those given, else those the session's last calibration used."""
    record = out_dir(root) / "dlt" / "calibration.json"
    previous = json.loads(record.read_text()).get("options", {}) if record.is_file() else {}
    chosen = {k: v for k, v in given.items() if v is not None}
    kept = {k: True for k in _SWITCHES if previous.get(k) and k not in chosen}
    if kept:
        names = ", ".join(f"--{k}" for k in kept)
        echo(f"  calibrate: keeping {names} from this session's last calibration")
    return {**kept, **chosen}


def read_dlt_files(root: Path, config: SessionConfig, required: bool = True) -> dict[str, DltFile]:
    """Every camera's calibration from ``out/dlt/<camera>.json`` (L1..L11, lens terms ...)."""
    result = {}
    for cam in config.camera_ids:
        path = out_dir(root) / "dlt" / f"{cam}.json"
        if path.is_file():
            result[cam] = read_dlt_json(path)
        elif required:
            raise KisscalError(f"{path}: missing; run `kisscal calibrate {root}` first")
    return result


# ----------------------------------------------------------------------------- rods


def _calibrate_rods(
    root: Path,
    config: SessionConfig,
    cameras: tuple[CameraConfig, ...],
    lins: dict[str, Linearisation],
    params: StageParams,
    echo: Echo,
    workers: int | None,
    whole_rig: bool,
) -> dict[str, Any]:
    """The seeds' route: rods recognised in every camera's rod frames, one DLT each."""
    assert config.rods is not None
    out = out_dir(root) / "dlt"
    rods = make_rods([(r.name, r.points_mm) for r in config.rods.rods])
    rod_frames = {
        cam.id: camera_frames(config.root, config.rods.images, cam.id, "rod") for cam in cameras
    }
    stage_key = cache_key(
        "calibrate",
        {c: file_keys(f.paths, config.root) for c, f in rod_frames.items()},
        linearisation_key({c: lins[c] for c in rod_frames}),
        params.detection,
        params.dlt,
        [(r.name, r.points_mm) for r in config.rods.rods],
    )
    if whole_rig and is_current(out / "check.json", stage_key):
        echo("  calibrate: cached (rod images, linearisation and parameters unchanged)")
        return {"_check": json.loads((out / "check.json").read_text())}
    blobs_px = {}
    for cam in steps(cameras, "calibrate: detect rods"):
        frames = rod_frames[cam.id]
        key = cache_key("detect", file_keys(frames.paths, config.root), params.detection)
        cache = out_dir(root) / "cache" / "blobs" / f"rods-{cam.id}.npz"
        sized = SizedFrames(frames, cam.id, cam.size_px)
        frame_blobs = detect_frames(
            sized, params.detection, cache, key, echo, f"rods {cam.id}", workers
        )
        blobs_px[cam.id] = [
            apply_linearisation(lins[cam.id], b.valid_only().xy_px) for b in frame_blobs
        ]
    t0 = time.perf_counter()
    cal = calibrate_rods(blobs_px, rods, params.dlt, leave_one_out=whole_rig)
    write_dlt_outputs(out, cal)
    rig = {k: v for k, v in cal.summary().items() if k != "cameras"}
    summary: dict[str, Any] = dict(cal.results)
    if whole_rig:
        write_json(out / "check.json", rig)
        mark_current(out / "check.json", stage_key)
        summary["_check"] = rig
    _say_rods(echo, cal, rig, time.perf_counter() - t0)
    _rod_figures(root, config, cal, rods)
    return summary


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


def _rod_figures(root: Path, config: SessionConfig, cal: RodCalibration, rods: Any) -> None:
    from kisscal.report.dlt import CameraResiduals

    sizes = {c.id: c.size_px for c in config.cameras}
    residuals = {
        c: CameraResiduals(cal.control_uv_px[c], r.residuals_px, sizes[c], r.rms_px)
        for c, r in cal.results.items()
    }
    figure(root, "dlt_residuals", "kisscal.report.dlt", "residual_figure", residuals)
    figure(
        root,
        "rig",
        "kisscal.report.dlt",
        "rig_figure",
        {c: r.centre_mm for c, r in cal.results.items()},
        [(r.name, r.points_mm) for r in rods],
        {c: r.R for c, r in cal.results.items()},
    )


# ------------------------------------------------------------------- control points


def _calibrate_points(
    root: Path,
    config: SessionConfig,
    cameras: tuple[CameraConfig, ...],
    lins: dict[str, Linearisation],
    params: StageParams,
    echo: Echo,
) -> dict[str, DltResult]:
    """Control points given per camera (``u_px,v_px,x_mm,y_mm,z_mm``, raw pixels)."""
    assert config.calibration is not None
    summary = {}
    for cam in cameras:
        path = config.root / config.calibration.points.replace("{camera}", cam.id)
        uv_raw, xyz, labels = read_control_points_csv(path)
        uv = apply_linearisation(lins[cam.id], uv_raw)
        res = calibrate_camera(xyz, uv, params.dlt, cam.id)
        write_dlt_json(out_dir(root) / "dlt" / f"{cam.id}.json", cam.id, res, xyz, uv, labels)
        summary[cam.id] = res
        echo(
            f"  calibrate {cam.id}: {res.method}, {len(xyz)} control points, "
            f"rms {res.rms_px:.3f} px"
        )
    return summary
