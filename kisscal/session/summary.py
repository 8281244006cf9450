"""What a processed session reports: ``summary.json`` and the ``kisscal check`` gate."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kisscal.errors import MissingDataError
from kisscal.io.config import SessionConfig
from kisscal.io.files import read_json, write_json
from kisscal.io.store import SessionStore
from kisscal.session.inputs import writes_session


@dataclass(frozen=True)
class CheckFailure:
    """A figure over its limit in ``kisscal check``."""

    camera: str
    figure: str
    value: float
    limit: float


@writes_session
def check(
    root: Path,
    max_reproj_px: float | None = None,
    max_grid_px: float | None = None,
    max_3d_mm: float | None = None,
    *,
    config: SessionConfig,
) -> list[CheckFailure]:
    """``kisscal check``: every figure over its limit (an empty list when all pass).

    Reads the outputs of ``kisscal linearise`` and ``kisscal calibrate``; no truth needed.
    The limits are kept in ``out/limits.json``, so the report judges against them.
    """
    store = SessionStore(root)
    limits = {"max_grid_px": max_grid_px, "max_reproj_px": max_reproj_px, "max_3d_mm": max_3d_mm}
    write_json(store.limits_path, limits)  # the report judges against the limits checked
    failures = []
    per_camera = [("dlt", max_reproj_px, store.dlt_path, "calibrate")]
    if config.grid is not None:
        per_camera.insert(0, ("grid", max_grid_px, store.linearisation_path, "linearise"))
    for cam in config.camera_ids:
        for name, limit, path, command in per_camera:
            if limit is not None:
                value = _figure_from(path(cam), "rms_px", f"kisscal {command} {root}")
                if not value <= limit:
                    failures.append(CheckFailure(cam, f"{name} rms_px", value, limit))
    if max_3d_mm is not None:
        doc = store.calibration_doc("check")
        if doc is None:
            path = store.calibration_file("check")
            raise MissingDataError(f"{path}: missing; run `kisscal calibrate {root}` first")
        loo = doc.get("leave_one_rod_out", {})
        fallback = doc.get("leave_out_mean_mm", doc.get("rods_in_sample_mean_mm", np.nan))
        value = float(loo.get("mean_mm", fallback))
        what = "leave-one-rod-out mean mm" if loo else "held-out 3D mean mm"
        if not value <= max_3d_mm:
            failures.append(CheckFailure("all", what, value, max_3d_mm))
    return failures


def _figure_from(path: Path, key: str, command: str) -> float:
    doc = read_json(path)
    if doc is None:
        raise MissingDataError(f"{path}: missing; run `{command}` first")
    return float(doc[key])
