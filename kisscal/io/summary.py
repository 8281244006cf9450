"""``out/summary.json``: every quality figure of a processed session, read back from ``out/``.

The one reader of the stage outputs for a summary; the session writes it after a run and
the report falls back on it when ``summary.json`` is missing (a stage run alone).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from kisscal.io.calibration_record import LensModels
from kisscal.io.config import load_session
from kisscal.io.files import lookup, read_json, read_table
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
        for line in lookup(entry, "reconstruction", "warnings") or []
    ]
    summary = {"session": config.name, "cameras": cams, "rods": check, "trials": trials}
    summary["held_out"] = held_out_figures(check)
    summary["warnings"] = warnings
    # the calibration route, and the wand's or target's own figures when there are any
    docs = {name: store.calibration_doc(name) for name in ("calibration", "wand", "target")}
    if docs["calibration"] is not None:
        docs["calibration"] = {"route": docs["calibration"].get("route")}
    summary.update({name: doc for name, doc in docs.items() if doc is not None})
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
    for key, group in (("", "wand_held_out"), ("rods_alone_", "wand_held_out_rods_alone")):
        if (rms := lookup(check, group, "length_rms_error_mm")) is not None:
            out[f"{key}wand_length_rms_error_mm"] = rms
    if "lens_models" in check:
        out["camera_model"] = check["lens_models"]
    return out


def _camera_summary(store: SessionStore, cam: str, exports: dict[str, Any]) -> dict[str, Any]:
    entry: dict[str, Any] = {}
    fit = lookup(exports, "cameras_toml", cam)
    lens = lookup(exports, "dltdv", "lens_error", cam)
    if fit or lens:  # how closely cameras.toml / dltdv.csv follow this camera (px)
        entry["export"] = {
            "opencv_fit_rms_px": lookup(fit, "rms_px"),
            "opencv_fit_max_px": lookup(fit, "max_px"),
            "dltdv_corner_error_px": max(lookup(lens, "corners_px") or [0.0]),
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
        entry["dlt"] = {k: doc.get(k) for k in ("method", "rms_px", "centre_mm")}
        models = LensModels.read(doc)
        if models is not None:  # the held-out reprojection error of each model compared
            entry["dlt"]["model"] = models.chosen
            scores = models.models.items()
            entry["dlt"]["held_out_rms_px"] = {m: s.held_out_rms_px for m, s in scores}
    return entry


def _trial_summary(files: TrialFiles) -> dict[str, Any]:
    docs = {"tracking": files.tracking, "reconstruction": files.recon, "gait": files.gait}
    entry: dict[str, Any] = {name: read_json(path) for name, path in docs.items() if path.is_file()}
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


def _str(value: Any) -> str | None:
    return None if value is None else str(value)


def _centre(value: Any) -> tuple[float, ...] | None:
    return (
        tuple(map(_float, value)) if isinstance(value, list | tuple) and len(value) == 3 else None
    )


#: How a figure of a summary entry becomes a record's field, after the field's declared
#: type: the one place where a figure not measured gets its missing value.
_AS: dict[str, Callable[[Any], Any]] = {
    "float": _float,
    "int | None": lambda v: None if v is None else int(v),
    "str | None": _str,
    "bool": bool,
    "tuple[str, ...]": lambda v: tuple(map(str, v or ())),
    "tuple[int, ...] | None": lambda v: None if v is None else tuple(map(int, v)),
    "tuple[float, float, float] | None": _centre,
}
_R = TypeVar("_R")


def _key(*path: str) -> Any:
    """A record's field read at ``path`` of its summary entry (see :func:`_read`)."""
    return field(metadata={"path": path})


def _read(cls: type[_R], doc: Any, **given: Any) -> _R:
    """Record ``cls`` from a summary entry: each field not ``given`` read at its path (its
    own name by default), converted after its declared type by :data:`_AS`."""
    for f in fields(cls):  # type: ignore[arg-type]
        if f.name not in given:
            given[f.name] = _AS[str(f.type)](lookup(doc, *f.metadata.get("path", (f.name,))))
    return cls(**given)


@dataclass(frozen=True)
class CameraFigures:
    """One camera's entry of ``summary.json`` (as :func:`summarise` writes it), typed.

    Figures not measured (no grid, not calibrated, not exported) are NaN or None.
    """

    grid: bool
    grid_rms_px_before: float = _key("grid", "rms_px_before")
    grid_rms_px: float = _key("grid", "rms_px")
    dots_used: int | None = _key("grid", "dots_used")
    dlt_method: str | None = _key("dlt", "method")
    dlt_rms_px: float = _key("dlt", "rms_px")
    centre_mm: tuple[float, float, float] | None = _key("dlt", "centre_mm")
    exported: bool = _key("export")
    export_fit_rms_px: float = _key("export", "opencv_fit_rms_px")

    @classmethod
    def read(cls, summary: Mapping[str, Any], camera: str) -> CameraFigures:
        """The figures of ``camera`` in a summary (all missing when it has none)."""
        return _read(cls, lookup(summary, "cameras", camera))


@dataclass(frozen=True)
class TrialFigures:
    """One trial's entry of ``summary.json``, typed: reconstruction and tracking figures,
    and why the trial failed (``failed_trials``) if it did."""

    processed: bool
    points: int | None = _key("reconstruction", "points")
    fields: int | None = _key("reconstruction", "fields")
    rms_px_median: float = _key("reconstruction", "rms_px_median")
    points_by_n_cameras: tuple[int, ...] | None = _key("reconstruction", "points_by_n_cameras")
    fits_marker_set: bool = _key("tracking", "fits_marker_set")
    missing: tuple[str, ...] = _key("tracking", "missing")
    flagged: tuple[str, ...] = _key("tracking", "flagged")
    failed: str | None

    @classmethod
    def read(cls, summary: Mapping[str, Any], trial: str) -> TrialFigures:
        """The figures of ``trial`` in a summary (not processed when it has none)."""
        entry = lookup(summary, "trials", trial)
        failed = lookup(summary, "failed_trials", trial)
        return _read(cls, entry, processed=entry is not None, failed=_str(failed or None))


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

    in_sample_mean_mm: float = _key("rods_in_sample_mean_mm")
    in_sample_max_mm: float = _key("rods_in_sample_max_mm")
    leave_one_rod_out_mean_mm: float = _key("leave_one_rod_out", "mean_mm")
    leave_one_rod_out_max_mm: float = _key("leave_one_rod_out", "max_mm")
    per_rod: tuple[RodHeldOut, ...]
    held_out_points: int | None
    leave_out_mean_mm: float
    leave_out_max_mm: float

    @classmethod
    def read(cls, summary: Mapping[str, Any]) -> RigCheck:
        """The check of a summary (every figure NaN when the calibration has none)."""
        rods = lookup(summary, "rods")
        per_rod = lookup(rods, "leave_one_rod_out", "per_rod")
        per_rod = per_rod.items() if isinstance(per_rod, Mapping) else ()
        return _read(
            cls,
            rods,
            per_rod=tuple(
                _read(RodHeldOut, r, name=str(n)) for n, r in per_rod if isinstance(r, Mapping)
            ),
        )
