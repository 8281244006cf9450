"""``out/summary.json``: every quality figure of a processed session, read back from ``out/``.

The one reader of the stage outputs for a summary; the session writes it after a run and
the report falls back on it when ``summary.json`` is missing (a stage run alone).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.io.config import load_session
from kisscal.io.files import read_table
from kisscal.tracking.tracks import STATUS_NAMES


def summarise(root: Path) -> dict[str, Any]:
    """Every quality figure of a processed session, read back from ``out/``."""
    config = load_session(Path(root))
    out = Path(root) / "out"
    exports_path = out / "exports.json"
    exports = json.loads(exports_path.read_text()) if exports_path.is_file() else {}
    cams = {cam: _camera_summary(out, cam, exports) for cam in config.camera_ids}
    trials = {t.name: _trial_summary(out / "trials" / t.name) for t in config.trials}
    check_path = out / "dlt" / "check.json"
    check = json.loads(check_path.read_text()) if check_path.is_file() else {}
    warnings = [
        f"{name}: {line}"
        for name, entry in trials.items()
        for line in entry.get("reconstruction", {}).get("warnings", [])
    ]
    summary = {"session": config.name, "cameras": cams, "rods": check, "trials": trials}
    summary["held_out"] = held_out_figures(check)
    summary["warnings"] = warnings
    summary.update(_calibration_summary(out / "dlt"))
    return summary


def held_out_figures(check: dict[str, Any]) -> dict[str, Any]:
    """The calibration's held-out figures, from ``dlt/check.json`` (contract v3): points no
    fit saw, reconstructed by the rig; not the in-sample residuals."""
    out: dict[str, Any] = {"route": check.get("route", "rods")} if check else {}
    loo = check.get("leave_one_rod_out") or {}
    if "mean_mm" in loo:
        out["leave_one_rod_out_mean_mm"] = loo["mean_mm"]
        out["leave_one_rod_out_max_mm"] = loo.get("max_mm")
    if loo.get("rods_alone_mean_mm") is not None:
        out["rods_alone_leave_one_rod_out_mean_mm"] = loo["rods_alone_mean_mm"]
    if "kept" in check:
        out["kept"] = check["kept"]
    if "held_out_points" in check and "leave_out_mean_mm" in check:
        out["held_out_points"] = check["held_out_points"]
        out["held_out_points_mean_mm"] = check["leave_out_mean_mm"]
        out["held_out_points_max_mm"] = check.get("leave_out_max_mm")
    wand = (check.get("wand_held_out") or {}).get("length_rms_error_mm")
    if wand is not None:
        out["wand_length_rms_error_mm"] = wand
    if "lens_models" in check:
        out["camera_model"] = check["lens_models"]
    return out


def _calibration_summary(dlt: Path) -> dict[str, Any]:
    """The calibration route, and the wand's or target's own figures when there are any."""
    entry: dict[str, Any] = {}
    record = dlt / "calibration.json"
    if record.is_file():
        entry["calibration"] = {"route": json.loads(record.read_text()).get("route")}
    for name in ("wand", "target"):
        path = dlt / f"{name}.json"
        if path.is_file():
            entry[name] = json.loads(path.read_text())
    return entry


def _camera_summary(out: Path, cam: str, exports: dict[str, Any]) -> dict[str, Any]:
    entry: dict[str, Any] = {}
    fit = exports.get("cameras_toml", {}).get(cam)
    lens = exports.get("dltdv", {}).get("lens_error", {}).get(cam)
    if fit or lens:  # how closely cameras.toml / dltdv.csv follow this camera (px)
        entry["export"] = {
            "opencv_fit_rms_px": (fit or {}).get("rms_px"),
            "opencv_fit_max_px": (fit or {}).get("max_px"),
            "dltdv_corner_error_px": max((lens or {}).get("corners_px", [0.0]) or [0.0]),
        }
    lin_path = out / "linearisation" / f"{cam}.json"
    if lin_path.is_file():
        doc = json.loads(lin_path.read_text())
        entry["grid"] = {
            k: v for k, v in doc.items() if isinstance(v, (int, float)) and k != "scale_px"
        }
    det_path = out / "detection" / f"{cam}.json"
    if det_path.is_file():
        kinds = json.loads(det_path.read_text()).get("kinds", {})
        entry["detection"] = {
            kind: {k: v["value"] for k, v in doc.get("settings", {}).items()}
            for kind, doc in kinds.items()
        }
    dlt_path = out / "dlt" / f"{cam}.json"
    if dlt_path.is_file():
        doc = json.loads(dlt_path.read_text())
        entry["dlt"] = {
            "method": doc.get("method"),
            "rms_px": doc.get("rms_px"),
            "centre_mm": doc.get("centre_mm"),
        }
        models = doc.get("lens_models")
        if models:  # the held-out reprojection error of each model compared
            entry["dlt"]["model"] = models["chosen"]
            entry["dlt"]["held_out_rms_px"] = {
                m: v.get("held_out_rms_px") for m, v in models["models"].items()
            }
    return entry


def _trial_summary(tdir: Path) -> dict[str, Any]:
    entry: dict[str, Any] = {}
    if (tdir / "tracking.json").is_file():
        entry["tracking"] = json.loads((tdir / "tracking.json").read_text())
    if (tdir / "recon.json").is_file():
        entry["reconstruction"] = json.loads((tdir / "recon.json").read_text())
    if (tdir / "gait.json").is_file():
        entry["gait"] = json.loads((tdir / "gait.json").read_text())
    if (tdir / "trajectories.csv").is_file():
        tr = read_table(tdir / "trajectories.csv")
        labels = sorted(set(tr["label"].tolist()))
        entry["trajectories"] = len(labels)
        entry["labels"] = labels
        status = tr["status"]
        status = np.where(status == "filled", "filled_spline", status.astype(str))
        entry["samples"] = {s: int(np.sum(status == s)) for s in STATUS_NAMES}
        # "filled" stays the count of every filled sample, how each was filled beside it
        entry["samples"]["filled"] = int(np.sum(np.char.startswith(status, "filled")))
    return entry
