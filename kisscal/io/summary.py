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
    summary["warnings"] = warnings
    summary.update(_calibration_summary(out / "dlt"))
    return summary


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
