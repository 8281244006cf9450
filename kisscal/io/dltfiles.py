"""DLT parameter files: ``out/dlt/<camera>.json`` and ``out/dlt/dltdv.csv`` (DESIGN.md).

Both can be read back, so a lab can bring DLT coefficients from another tool:

* ``<camera>.json``: at least ``{"camera": ..., "L": [11 numbers]}``; kisscal writes the
  method, ``rms_px`` (= sqrt(mean(du^2 + dv^2)), stated in the file), per-point
  residuals and what each point is (``kind``, :data:`POINT_KINDS`), the camera centre, K,
  R, Hatze's constraint violation and lens terms.
* ``dltdv.csv``: 11 rows (L1..L11), one column per camera, no header, in DLTdv8's pixel
  convention (:data:`DLTDV8_CONVENTION`; DLTdv8 reads it with ``dlmread``). An optional
  first row of camera names is accepted when reading.

kisscal's own pixel convention (:data:`PIXEL_CONVENTION`) puts the top-left pixel's centre
at (0, 0); DLTdv8 shows images with MATLAB's ``image``, which puts it at (1, 1), and
records clicks in those axes (v down; DLTdv7 and older used a lower-left origin, v up).
The 1 px shift is exact in the coefficients (:func:`kisscal.dlt.model.shift_dlt_pixels`).
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.dlt.model import dlt_to_matrix, shift_dlt_pixels
from kisscal.dlt.nonlinear import lens_frame
from kisscal.dlt.params import DltResult
from kisscal.dlt.rig import RodCalibration
from kisscal.errors import InputError, MissingDataError
from kisscal.io.files import read_json, read_text, write_csv, write_text

RMS_DEFINITION = "sqrt(mean(du^2 + dv^2)) over control points, pixels (Euclidean RMS)"
#: kisscal's pixel coordinates (L of ``<camera>.json`` maps to these, linearised).
PIXEL_CONVENTION = (
    "origin at the centre of the top-left pixel (0, 0), u to the right, v down, in "
    "linearised pixels (apply linearisation/<camera>.json to raw pixels first)"
)
#: The pixel coordinates of ``dltdv.csv`` (DLTdv8: MATLAB image axes).
DLTDV8_CONVENTION = (
    "DLTdv8: the centre of the top-left pixel is (1, 1), u to the right, v down "
    "(kisscal's coordinates + 1); DLTdv7 and older use a lower-left origin, v up"
)
#: kisscal pixel + this = DLTdv8 pixel.
DLTDV8_OFFSET_PX = (1.0, 1.0)

#: What a control point of ``<camera>.json`` is (its ``kind``), by the route that made
#: it. A label is a name (a lab may name a rod ``W1``); the kind says which points are
#: the lab's own (:func:`kisscal.session.exports.measured_points` leaves out a wand's).
POINT_KINDS = {
    "rod": "a rod's surveyed marker ([rods])",
    "points": "a surveyed control point of [calibration] points",
    "target": "a target's dot ([target])",
    "wand": "a wand's marker in one field, placed by the wand's adjustment ([wand])",
    "trial": "a trial's marker adjusted with the cameras (its position estimated)",
}


@dataclass(frozen=True)
class DltFile:
    """DLT parameters read from a file.

    Attributes
    ----------
    camera : str
    L : ndarray, shape (11,)
        L1..L11 (lab mm -> linearised pixels).
    method : str
        As written (``"dlt"``, ``"mdlt"``, ``"refined"``) or ``"external"`` when absent.
    lens : ndarray, shape (5,) or None
        Kolahi's L12..L16 when present.
    rms_px : float
        NaN when the file does not give it.
    n_points : int or None
        Control points the DLT was fitted to, when the file says.
    missing_rod_markers : tuple of str
        Rod markers the camera did not see (rods route).
    data : dict
        The whole JSON document (empty for dltdv.csv).
    """

    camera: str
    L: NDArray[np.float64]
    method: str = "external"
    lens: NDArray[np.float64] | None = None
    rms_px: float = math.nan
    n_points: int | None = None
    missing_rod_markers: tuple[str, ...] = ()
    data: dict[str, Any] | None = None


#: What ``lens`` held before the terms were made radial in square pixels: the same
#: numbers mean another lens when the pixels are not square.
PIXEL_UNIT_LENS_MODEL = "Kolahi et al. 2007 eq. 2 (L12..L16), applied to observed pixels"

#: What ``lens`` holds, written beside it.
LENS_MODEL = (
    "Kolahi et al. 2007 eq. 2 (L12..L16), applied to observed pixels, radial about the "
    "principal point in square pixels (the v offset scaled by fu / fv)"
)


def _floats(a: ArrayLike) -> list:
    return np.asarray(a, dtype=float).tolist()


def write_dlt_json(
    path: str | Path,
    camera: str,
    result: DltResult,
    xyz_mm: ArrayLike | None = None,
    uv_px: ArrayLike | None = None,
    labels: Sequence[str] | None = None,
    extra: Mapping[str, Any] | None = None,
    kinds: str | Sequence[str] | None = None,
) -> Path:
    """Write ``out/dlt/<camera>.json``.

    Parameters
    ----------
    path : path
        File to write (parent folders are created).
    camera : str
        Camera id.
    result : DltResult
        The calibration.
    xyz_mm, uv_px, labels : optional
        Control points (as fitted) and their names (e.g. ``"R1.1"``), for the
        per-point residual table.
    extra : mapping, optional
        More keys (e.g. rod recognition report, linearisation used).
    kinds : str or sequence of str
        What each control point is (:data:`POINT_KINDS`), one for all or one per point;
        required when there are control points.
    """
    doc: dict[str, Any] = {
        "camera": camera,
        "L": _floats(result.L),
        "method": result.method,
        "rms_px": float(result.rms_px),
        "rms_definition": RMS_DEFINITION,
        "n_points": len(result.residuals_px),
        "centre_mm": _floats(result.centre_mm),
        "K": _floats(result.K),
        "R": _floats(result.R),
        "constraint_violation": float(result.constraint),
        "constraint_violation_linear": float(result.constraint_linear),
        "lens": None if result.lens is None else _floats(result.lens),
        "lens_model": LENS_MODEL,
        "iterations": int(result.iterations),
        "pixel_convention": PIXEL_CONVENTION,
        "dltdv_csv_convention": DLTDV8_CONVENTION,
    }
    n = len(result.residuals_px)
    labels = list(labels) if labels is not None else [f"P{i + 1}" for i in range(n)]
    xyz = np.full((n, 3), np.nan) if xyz_mm is None else np.asarray(xyz_mm, dtype=float)
    uv = np.full((n, 2), np.nan) if uv_px is None else np.asarray(uv_px, dtype=float)
    if len(labels) != n or xyz.shape != (n, 3) or uv.shape != (n, 2):
        raise ValueError("labels, xyz_mm and uv_px must match the result's control points")
    kind = _kinds(kinds, n)
    doc["points"] = [
        {
            "label": lab,
            "kind": k,
            "x_mm": x[0],
            "y_mm": x[1],
            "z_mm": x[2],
            "u_px": u[0],
            "v_px": u[1],
            "du_px": r[0],
            "dv_px": r[1],
        }
        for lab, k, x, u, r in zip(
            labels, kind, xyz.tolist(), uv.tolist(), _floats(result.residuals_px), strict=True
        )
    ]
    if extra:
        doc.update(extra)
    path = Path(path)
    write_text(path, json.dumps(doc, indent=1, allow_nan=True) + "\n")
    return path


def _kinds(kinds: str | Sequence[str] | None, n: int) -> list[str]:
    """One :data:`POINT_KINDS` entry per control point (``kinds`` one for all or each)."""
    if n and kinds is None:
        raise ValueError("the control points need their kind (POINT_KINDS)")
    listed = [kinds] * n if isinstance(kinds, str) else list(kinds or ())
    if len(listed) != n or not set(listed) <= POINT_KINDS.keys():
        raise ValueError(f"kinds must be {n} of {', '.join(POINT_KINDS)}, got {kinds!r}")
    return listed


def read_dlt_json(path: str | Path) -> DltFile:
    """Read a ``<camera>.json`` DLT file (kisscal's or any with ``camera`` and ``L``).

    Raises
    ------
    KisscalError
        Missing file, invalid JSON, or no 11 finite numbers under ``L``.
    """
    path = Path(path)
    doc = read_json(path)
    if doc is None:
        raise MissingDataError(f"{path}: DLT file not found")
    if not isinstance(doc, dict) or "L" not in doc:
        raise InputError(f'{path}: a DLT file needs an "L" list of 11 numbers')
    L = _eleven(doc["L"], f'{path}: "L"')
    lens = doc.get("lens")
    if lens is not None:
        lens = np.asarray(lens, dtype=float)
        if lens.shape != (5,):
            raise InputError(f'{path}: "lens" must hold 5 numbers (L12..L16)')
        if doc.get("lens_model") == PIXEL_UNIT_LENS_MODEL and not _square_pixels(L):
            raise InputError(
                f"{path}: its lens terms are in the pixel-unit form of an older kisscal, "
                "which differs on non-square pixels; run `kisscal calibrate` again"
            )
    return DltFile(
        camera=str(doc.get("camera", path.stem)),
        L=L,
        method=str(doc.get("method", "external")),
        lens=lens,
        rms_px=float(doc.get("rms_px", math.nan)),
        n_points=int(doc["n_points"]) if doc.get("n_points") is not None else None,
        missing_rod_markers=tuple(str(m) for m in (doc.get("rods") or {}).get("missing", ())),
        data=doc,
    )


def _square_pixels(L: NDArray[np.float64]) -> bool:
    """Whether the camera of DLT ``L`` has square, unskewed pixels (within 0.1 %)."""
    _, A = lens_frame(dlt_to_matrix(L))
    return bool(np.allclose(A, np.eye(2), atol=1e-3))


def _eleven(values: Any, where: str) -> NDArray[np.float64]:
    try:
        L = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{where} must be 11 numbers") from None
    if L.shape != (11,) or not np.isfinite(L).all():
        raise InputError(f"{where} must be 11 finite numbers, got shape {L.shape}")
    return L


def write_dltdv_csv(path: str | Path, L_by_camera: Mapping[str, ArrayLike]) -> Path:
    """Write ``dltdv.csv``: 11 rows (L1..L11), one column per camera, in mapping order,
    converted from kisscal's pixel convention to DLTdv8's (:data:`DLTDV8_CONVENTION`)."""
    cols = [
        shift_dlt_pixels(_eleven(L, f"camera {cam}: L"), DLTDV8_OFFSET_PX)
        for cam, L in L_by_camera.items()
    ]
    return write_csv(path, None, ([repr(float(x)) for x in row] for row in np.array(cols).T))


def read_dltdv_csv(path: str | Path, cameras: Sequence[str] | None = None) -> dict[str, DltFile]:
    """Read an 11-row DLT coefficient CSV (one column per camera).

    Parameters
    ----------
    path : path
        The CSV. A first row of camera names is allowed.
    cameras : sequence of str, optional
        Camera ids in column order (session.toml order); required unless the file has a
        header row; when both are given they must agree in number.

    Returns
    -------
    dict
        Camera id -> :class:`DltFile` (method ``"external"``), L in kisscal's pixel
        convention (the file's, DLTdv8's, shifted back by 1 px).
    """
    path = Path(path)
    text = read_text(path, "DLT coefficient file")
    rows = [r for r in csv.reader(text.splitlines()) if any(c.strip() for c in r)]
    header = None
    if rows:
        try:
            [float(c) for c in rows[0]]
        except ValueError:
            header = [c.strip() for c in rows[0]]
            rows = rows[1:]
    if len(rows) != 11:
        raise InputError(f"{path}: expected 11 rows of DLT coefficients, got {len(rows)}")
    try:
        table = np.array([[float(c) for c in r] for r in rows])
    except ValueError:
        raise InputError(f"{path}: DLT coefficients must be numbers") from None
    n_cam = table.shape[1]
    names = list(cameras) if cameras is not None else header
    if names is None:
        raise InputError(f"{path}: no header row; give the camera ids in column order")
    if len(names) != n_cam:
        raise InputError(f"{path}: {n_cam} columns of coefficients for {len(names)} cameras")
    back = -np.asarray(DLTDV8_OFFSET_PX)
    return {
        cam: DltFile(
            camera=cam, L=shift_dlt_pixels(_eleven(table[:, i], f"{path}: column {i + 1}"), back)
        )
        for i, cam in enumerate(names)
    }


CONTROL_COLUMNS = ("u_px", "v_px", "x_mm", "y_mm", "z_mm")


def read_control_points_csv(
    path: str | Path,
) -> tuple[NDArray[np.float64], NDArray[np.float64], tuple[str, ...]]:
    """Read ``[calibration] points`` control points of one camera (DESIGN.md).

    Columns ``u_px,v_px,x_mm,y_mm,z_mm`` (raw pixel coordinates, not yet linearised) and
    optionally ``label``; other columns are an error, so typos are not silently ignored.

    Returns
    -------
    uv_px : ndarray, shape (N, 2)
    xyz_mm : ndarray, shape (N, 3)
    labels : tuple of str
        The ``label`` column, or ``P1``, ``P2``, ... .
    """
    path = Path(path)
    text = read_text(path, "control point file")
    reader = csv.DictReader(text.splitlines())
    fields = [f.strip() for f in reader.fieldnames or []]
    missing = [c for c in CONTROL_COLUMNS if c not in fields]
    unknown = [f for f in fields if f not in (*CONTROL_COLUMNS, "label")]
    if missing or unknown:
        raise InputError(
            f"{path}: control points need columns {','.join(CONTROL_COLUMNS)}[,label]"
            + (f"; missing {', '.join(missing)}" if missing else "")
            + (f"; unknown {', '.join(unknown)}" if unknown else "")
        )
    rows = [{k.strip(): v for k, v in r.items()} for r in reader]
    try:
        table = np.array([[float(r[c]) for c in CONTROL_COLUMNS] for r in rows]).reshape(-1, 5)
    except (TypeError, ValueError):
        raise InputError(f"{path}: control point coordinates must be numbers") from None
    labels = tuple((r.get("label") or f"P{i + 1}").strip() for i, r in enumerate(rows))
    return table[:, :2], table[:, 2:], labels


def write_dlt_outputs(
    calibration: RodCalibration, dlt_path: Callable[[str], Path], dltdv_path: Path
) -> list[Path]:
    """Write every camera's DLT JSON file (at ``dlt_path(camera)``) and the DLTdv table.

    ``calibration`` is the result of :func:`kisscal.dlt.calibrate_rods`; the JSON files also
    carry the rod recognition report (markers missing, unused blobs) and the rig's
    in-sample and leave-one-rod-out 3D errors. The session's paths are
    :meth:`kisscal.io.store.SessionStore.dlt_path` and ``dltdv_path``. Returns the paths
    written.
    """
    paths = []
    summary = calibration.summary()
    for cam, result in calibration.results.items():
        match = calibration.matches[cam]
        extra = {
            "rods": {
                "missing": list(match.missing),
                "fit_rms_px": dict(zip(match.rod_names, match.fit_rms_px.tolist(), strict=True)),
                "unused_blobs": len(match.unused_blobs),
            },
            "rig": {k: v for k, v in summary.items() if k != "cameras"},
        }
        if calibration.models is not None:
            extra["lens_models"] = calibration.models.camera_dict(cam)
        paths.append(
            write_dlt_json(
                dlt_path(cam),
                cam,
                result,
                calibration.control_xyz_mm[cam],
                calibration.control_uv_px[cam],
                calibration.labels[cam],
                extra,
                kinds="rod",
            )
        )
    paths.append(write_dltdv_csv(dltdv_path, {c: r.L for c, r in calibration.results.items()}))
    return paths
