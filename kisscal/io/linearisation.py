"""Read and write ``out/linearisation/<camera>.json`` (DESIGN.md, public contract v1).

The file holds everything needed to apply the correction without kisscal: with
``un = (u - cu) / s``, ``vn = (v - cv) / s`` and the 15 terms
``1, u, v, u², uv, v², u³, u²v, uv², v³, u⁴, u³v, u²v², uv³, v⁴`` of (un, vn),
``u' = x · t`` and ``v' = y · t`` in px.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from kisscal.errors import InputError, KisscalError, MissingDataError, with_context
from kisscal.grid.poly import TERM_NAMES, Linearisation, LinearisationQuality
from kisscal.io.files import read_json, write_text

FORMAT_VERSION = 1
_QUALITY_KEYS = {f.name for f in fields(LinearisationQuality)}


def _number(value: float | None) -> float | None:
    """JSON has no NaN: write None for a figure that could not be measured."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def linearisation_to_dict(
    lin: Linearisation,
    camera: str,
    missing_rc: ArrayLike | None = None,
    missing_uv: ArrayLike | None = None,
    refined: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The JSON document of one camera's linearisation (DESIGN.md format).

    Parameters
    ----------
    lin : Linearisation
        Coefficients, normalisation and (optionally) quality figures.
    camera : str
        Camera id.
    missing_rc, missing_uv : array_like, optional
        Grid positions without a dot and where they would be (px), for the record.
    refined : mapping, optional
        For a linearisation a calibration route estimated (a wand's lens terms): at least
        ``{"by": route}``, plus ``"grid_fit"`` (the grid's own linearisation document, or
        None without a grid) and what the route adds. Written under ``"refined"``.
    """
    doc: dict[str, Any] = {
        "format_version": FORMAT_VERSION,
        "camera": camera,
        "model": "poly4",
        "center_px": [float(lin.center_px[0]), float(lin.center_px[1])],
        "scale_px": float(lin.scale_px),
        "terms": list(TERM_NAMES),
        "x": [float(c) for c in lin.x],
        "y": [float(c) for c in lin.y],
    }
    q = lin.quality
    if q is not None:
        doc["grid"] = {"rows": q.rows, "cols": q.cols}
        doc["optimal_grid"] = q.optimal_model
        doc["dots_used"] = q.dots_used
        doc["rms_px_before"] = _number(q.residual_rms_before_px)
        doc["rms_px"] = _number(q.residual_rms_after_px)
        doc["quality"] = {
            k: (_number(v) if isinstance(v, float) else v) for k, v in asdict(q).items()
        }
    if refined is not None:
        doc["refined"] = dict(refined)
    if missing_rc is not None:
        rc = np.asarray(missing_rc, dtype=int).reshape(-1, 2)
        doc["missing"] = [{"row": int(r), "col": int(c)} for r, c in rc]
        if missing_uv is not None:
            uv = np.asarray(missing_uv, dtype=float).reshape(-1, 2)
            for item, (u, v) in zip(doc["missing"], uv, strict=True):
                item["u_px"], item["v_px"] = float(u), float(v)
    return doc


def linearisation_from_dict(doc: dict[str, Any], source: str = "linearisation") -> Linearisation:
    """Parse a linearisation document; only ``center_px``, ``scale_px``, ``x``, ``y`` are needed.

    Raises
    ------
    KisscalError
        Missing keys, wrong model, wrong lengths or non-numbers, naming ``source``.
    """
    if not isinstance(doc, dict):
        raise InputError(f"{source}: expected a JSON object")
    model = doc.get("model", "poly4")
    if model != "poly4":
        raise InputError(f"{source}: unknown linearisation model {model!r} (expected 'poly4')")
    for key in ("center_px", "scale_px", "x", "y"):
        if key not in doc:
            raise InputError(f"{source}: missing key {key!r}")
    try:
        center = [float(c) for c in doc["center_px"]]
        scale = float(doc["scale_px"])
        x = np.array(doc["x"], dtype=float)
        y = np.array(doc["y"], dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{source}: coefficients must be numbers ({exc})") from None
    if len(center) != 2:
        raise InputError(f"{source}: center_px must hold 2 numbers, got {len(center)}")
    quality = None
    q = doc.get("quality")
    if isinstance(q, dict) and _QUALITY_KEYS <= set(q):
        values = {
            k: (float("nan") if q[k] is None and k != "pixel_aspect" else q[k])
            for k in _QUALITY_KEYS
        }
        quality = LinearisationQuality(**values)
    try:
        return Linearisation((center[0], center[1]), scale, x, y, quality)
    except KisscalError as exc:
        raise with_context(exc, f"{source}: ") from None


def write_linearisation(
    path: str | Path,
    lin: Linearisation,
    camera: str,
    missing_rc: ArrayLike | None = None,
    missing_uv: ArrayLike | None = None,
    refined: Mapping[str, Any] | None = None,
) -> Path:
    """Write ``out/linearisation/<camera>.json``; creates the folder. Returns the path.

    ``refined`` marks a linearisation a calibration route estimated (see
    :func:`linearisation_to_dict`).
    """
    path = Path(path)
    doc = linearisation_to_dict(lin, camera, missing_rc, missing_uv, refined)
    write_text(path, json.dumps(doc, indent=2) + "\n")
    return path


def read_linearisation(path: str | Path) -> tuple[str, Linearisation]:
    """Read a linearisation file; returns ``(camera, linearisation)``.

    Raises
    ------
    KisscalError
        File missing, not JSON, or not a valid linearisation document.
    """
    path = Path(path)
    doc = read_json(path)
    if doc is None:
        raise MissingDataError(f"linearisation file not found: {path}")
    lin = linearisation_from_dict(doc, str(path))
    return str(doc.get("camera", path.stem)), lin


def read_linearisation_doc(path: str | Path) -> dict[str, Any] | None:
    """The JSON document of a linearisation file, or None when there is no file."""
    doc = read_json(Path(path))
    if doc is not None and not isinstance(doc, dict):
        raise InputError(f"{path}: expected a JSON object")
    return doc


def refined_by(doc: Mapping[str, Any] | None) -> str | None:
    """The calibration route that estimated this linearisation (None: a grid's own)."""
    refined = (doc or {}).get("refined")
    return str(refined.get("by")) if isinstance(refined, dict) else None


def grid_fit_of(doc: Mapping[str, Any], source: str) -> Linearisation | None:
    """The grid's own linearisation kept in a refined document (None: there was no grid)."""
    refined = doc.get("refined")
    if not isinstance(refined, dict):
        return linearisation_from_dict(dict(doc), source)
    grid = refined.get("grid_fit")
    return None if grid is None else linearisation_from_dict(grid, f"{source} (grid_fit)")
