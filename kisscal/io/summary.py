"""``out/summary.json``: every quality figure of a processed session, read back from ``out/``.

The one reader of the stage outputs for a summary; the session writes it after a run and
the report falls back on it when ``summary.json`` is missing (a stage run alone).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.io.calibration_record import LensModels
from kisscal.io.config import load_session
from kisscal.io.files import read_table
from kisscal.io.store import SessionStore, TrialFiles
from kisscal.tracking.tracks import STATUS_NAMES


def summarise(root: Path) -> dict[str, Any]:
    """Every quality figure of a processed session, read back from ``out/``."""
    config = load_session(Path(root))
    store = SessionStore(root)
    exports = store.read_json(store.exports_path) or {}
    cams = {cam: _camera_summary(store, cam, exports) for cam in config.camera_ids}
    trials = {t.name: _trial_summary(store.trial(t.name)) for t in config.trials}
    check = store.calibration_doc("check") or {}
    warnings = [
        f"{name}: {line}"
        for name, entry in trials.items()
        for line in entry.get("reconstruction", {}).get("warnings", [])
    ]
    summary = {"session": config.name, "cameras": cams, "rods": check, "trials": trials}
    summary["held_out"] = held_out_figures(check)
    summary["warnings"] = warnings
    summary.update(_calibration_summary(store))
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
    alone = (check.get("wand_held_out_rods_alone") or {}).get("length_rms_error_mm")
    if alone is not None:
        out["rods_alone_wand_length_rms_error_mm"] = alone
    if "lens_models" in check:
        out["camera_model"] = check["lens_models"]
    return out


def _calibration_summary(store: SessionStore) -> dict[str, Any]:
    """The calibration route, and the wand's or target's own figures when there are any."""
    entry: dict[str, Any] = {}
    record = store.calibration_doc("calibration")
    if record is not None:
        entry["calibration"] = {"route": record.get("route")}
    for name in ("wand", "target"):
        doc = store.calibration_doc(name)
        if doc is not None:
            entry[name] = doc
    return entry


def _camera_summary(store: SessionStore, cam: str, exports: dict[str, Any]) -> dict[str, Any]:
    entry: dict[str, Any] = {}
    fit = exports.get("cameras_toml", {}).get(cam)
    lens = exports.get("dltdv", {}).get("lens_error", {}).get(cam)
    if fit or lens:  # how closely cameras.toml / dltdv.csv follow this camera (px)
        entry["export"] = {
            "opencv_fit_rms_px": (fit or {}).get("rms_px"),
            "opencv_fit_max_px": (fit or {}).get("max_px"),
            "dltdv_corner_error_px": max((lens or {}).get("corners_px", [0.0]) or [0.0]),
        }
    doc = store.linearisation_doc(cam)
    if doc is not None:
        entry["grid"] = {
            k: v for k, v in doc.items() if isinstance(v, (int, float)) and k != "scale_px"
        }
    record = store.detection_record(cam)
    if record is not None:
        entry["detection"] = {kind: r.values() for kind, r in record.kinds.items()}
    doc = store.read_json(store.dlt_path(cam))
    if doc is not None:
        entry["dlt"] = {
            "method": doc.get("method"),
            "rms_px": doc.get("rms_px"),
            "centre_mm": doc.get("centre_mm"),
        }
        models = LensModels.read(doc)
        if models is not None:  # the held-out reprojection error of each model compared
            entry["dlt"]["model"] = models.chosen
            scores = models.models.items()
            entry["dlt"]["held_out_rms_px"] = {m: s.held_out_rms_px for m, s in scores}
    return entry


def _trial_summary(files: TrialFiles) -> dict[str, Any]:
    entry: dict[str, Any] = {}
    for name, path in (
        ("tracking", files.tracking),
        ("reconstruction", files.recon),
        ("gait", files.gait),
    ):
        if path.is_file():
            entry[name] = json.loads(path.read_text())
    if files.trajectories().is_file():
        tr = read_table(files.trajectories())
        labels = sorted(set(tr["label"].tolist()))
        entry["trajectories"] = len(labels)
        entry["labels"] = labels
        status = tr["status"]
        status = np.where(status == "filled", "filled_spline", status.astype(str))
        entry["samples"] = {s: int(np.sum(status == s)) for s in STATUS_NAMES}
        # "filled" stays the count of every filled sample, how each was filled beside it
        entry["samples"]["filled"] = int(np.sum(np.char.startswith(status, "filled")))
    return entry


def _float(value: Any) -> float:
    """A figure of the summary as a float (NaN where it was not measured)."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return math.nan


def _entry(doc: Any, *keys: str) -> dict[str, Any]:
    """``doc[k1][k2]...``, an empty dict where a level is missing or not a table."""
    for key in keys:
        doc = doc.get(key) if isinstance(doc, Mapping) else None
    return dict(doc) if isinstance(doc, Mapping) else {}


@dataclass(frozen=True)
class CameraFigures:
    """One camera's entry of ``summary.json`` (as :func:`summarise` writes it), typed.

    Figures not measured (no grid, not calibrated, not exported) are NaN or None.
    """

    grid: bool
    grid_rms_px_before: float
    grid_rms_px: float
    dots_used: int | None
    dlt_method: str | None
    dlt_rms_px: float
    centre_mm: tuple[float, float, float] | None
    exported: bool
    export_fit_rms_px: float

    @classmethod
    def read(cls, summary: Mapping[str, Any], camera: str) -> CameraFigures:
        """The figures of ``camera`` in a summary (all missing when it has none)."""
        entry = _entry(summary, "cameras", camera)
        grid, dlt, export = _entry(entry, "grid"), _entry(entry, "dlt"), _entry(entry, "export")
        centre = dlt.get("centre_mm")
        ok = isinstance(centre, list | tuple) and len(centre) == 3
        dots = grid.get("dots_used")
        return cls(
            grid=bool(grid),
            grid_rms_px_before=_float(grid.get("rms_px_before")),
            grid_rms_px=_float(grid.get("rms_px")),
            dots_used=int(dots) if isinstance(dots, int | float) else None,
            dlt_method=dlt.get("method"),
            dlt_rms_px=_float(dlt.get("rms_px")),
            centre_mm=tuple(map(_float, centre)) if ok else None,  # type: ignore[arg-type]
            exported="export" in entry,
            export_fit_rms_px=_float(export.get("opencv_fit_rms_px")),
        )


@dataclass(frozen=True)
class TrialFigures:
    """One trial's entry of ``summary.json``, typed: reconstruction and tracking figures,
    and why the trial failed (``failed_trials``) if it did."""

    processed: bool
    points: int | None
    fields: int | None
    rms_px_median: float
    points_by_n_cameras: tuple[int, ...] | None
    fits_marker_set: bool
    missing: tuple[str, ...]
    flagged: tuple[str, ...]
    failed: str | None

    @classmethod
    def read(cls, summary: Mapping[str, Any], trial: str) -> TrialFigures:
        """The figures of ``trial`` in a summary (not processed when it has none)."""
        processed = trial in _entry(summary, "trials")
        recon = _entry(summary, "trials", trial, "reconstruction")
        tracking = _entry(summary, "trials", trial, "tracking")
        by_n = recon.get("points_by_n_cameras")
        failed = _entry(summary, "failed_trials").get(trial)
        return cls(
            processed=processed,
            points=int(recon["points"]) if recon.get("points") is not None else None,
            fields=int(recon["fields"]) if recon.get("fields") else None,
            rms_px_median=_float(recon.get("rms_px_median")),
            points_by_n_cameras=tuple(int(n) for n in by_n) if by_n is not None else None,
            fits_marker_set=bool(tracking.get("fits_marker_set", False)),
            missing=tuple(tracking.get("missing", ())),
            flagged=tuple(tracking.get("flagged", ())),
            failed=str(failed) if failed else None,
        )


@dataclass(frozen=True)
class RodHeldOut:
    """One rod held out of the calibration and reconstructed by the others (mm)."""

    name: str
    n_markers: int | None
    mean_mm: float
    max_mm: float
    rods_alone_mean_mm: float


@dataclass(frozen=True)
class RigCheck:
    """The calibration's 3D check (``dlt/check.json``, ``rods`` in ``summary.json``),
    typed: rod markers in the fit, each rod held out, target points held out (mm)."""

    in_sample_mean_mm: float
    in_sample_max_mm: float
    leave_one_rod_out_mean_mm: float
    leave_one_rod_out_max_mm: float
    per_rod: tuple[RodHeldOut, ...]
    held_out_points: int | None
    leave_out_mean_mm: float
    leave_out_max_mm: float

    @classmethod
    def read(cls, summary: Mapping[str, Any]) -> RigCheck:
        """The check of a summary (every figure NaN when the calibration has none)."""
        rods = _entry(summary, "rods")
        loo = _entry(rods, "leave_one_rod_out")
        per_rod = tuple(
            RodHeldOut(
                str(name),
                int(r["n_markers"]) if r.get("n_markers") is not None else None,
                _float(r.get("mean_mm")),
                _float(r.get("max_mm")),
                _float(r.get("rods_alone_mean_mm")),
            )
            for name, r in _entry(loo, "per_rod").items()
            if isinstance(r, Mapping)
        )
        held = rods.get("held_out_points")
        return cls(
            in_sample_mean_mm=_float(rods.get("rods_in_sample_mean_mm")),
            in_sample_max_mm=_float(rods.get("rods_in_sample_max_mm")),
            leave_one_rod_out_mean_mm=_float(loo.get("mean_mm")),
            leave_one_rod_out_max_mm=_float(loo.get("max_mm")),
            per_rod=per_rod,
            held_out_points=int(held) if held is not None else None,
            leave_out_mean_mm=_float(rods.get("leave_out_mean_mm")),
            leave_out_max_mm=_float(rods.get("leave_out_max_mm")),
        )
