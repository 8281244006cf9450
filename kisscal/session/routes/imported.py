"""Calibrations made elsewhere: ``[calibration] cameras`` (an anipose / Pose2Sim
``cameras.toml``) and ``[calibration] dlt`` (DLTdv coefficients, 11 rows x cameras).

Both write the version-1 files, so everything downstream is unchanged:

* ``cameras``: ``linearisation/<camera>.json`` (model ``poly4``) and
  ``dlt/<camera>.json`` (the DLT of ``K [R | t]``, method ``"cameras"``, with the lens
  terms L12..L16 when they help), fitted together to the file's OpenCV distortion over
  the image, within the region kisscal's export fitted when the file gives it
  (:func:`kisscal.opencv.camera_from_opencv`; :func:`imported_linearisation`
  is called by ``kisscal linearise``).
* ``dlt``: ``dlt/<camera>.json`` (the file's coefficients in kisscal's pixel convention,
  method ``"dltdv"``); the linearisation is the grid's, or none (DLTdv has no lens model).
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.dlt.calibrate import dlt_result
from kisscal.dlt.camera import hatze_violation
from kisscal.dlt.params import DltResult
from kisscal.errors import InputError, KisscalError, MissingDataError
from kisscal.grid import Linearisation
from kisscal.io.cameras_toml import read_cameras_toml, read_fit_regions
from kisscal.io.config import CameraConfig, SessionConfig
from kisscal.io.dltfiles import DltFile, read_dltdv_csv, write_dlt_json
from kisscal.io.files import write_text
from kisscal.io.linearisation import linearisation_to_dict
from kisscal.io.store import SessionStore
from kisscal.opencv import camera_from_opencv
from kisscal.session.progress import Echo, quiet
from kisscal.session.routes import RouteInputs
from kisscal.session.runner import run_keyed


def _source(config: SessionConfig, key: str) -> Path:
    if config.calibration is None:
        raise InputError(f"{config.path}: no [calibration] table to import from")
    path = config.root / str(getattr(config.calibration, key))
    if not path.is_file():
        raise MissingDataError(f"{path}: calibration.{key} file not found")
    return path


def _names(config: SessionConfig) -> dict[str, str]:
    """``[calibration] names``: the file's camera names -> session camera ids."""
    return dict(config.calibration.names) if config.calibration is not None else {}


#: Above this RMS (px) the polynomial does not follow the imported lens well (a warning).
POLY_FIT_WARN_PX = 0.05


def imported_linearisation(
    config: SessionConfig, cam: CameraConfig, echo: Echo = quiet
) -> Linearisation:
    """The linearisation of ``cam`` fitted to the OpenCV distortion of ``[calibration]
    cameras``; written to ``out/linearisation/<camera>.json`` with the fit's RMS over the
    image (``fit_rms_px``), cached on the file. A 4th-order polynomial follows moderate
    lenses to a few hundredths of a pixel, strong ones less well: above
    :data:`POLY_FIT_WARN_PX` a warning says so."""
    path = _source(config, "cameras")
    store = SessionStore(config.root)
    out = store.linearisation_path(cam.id)
    stage = ("imported-linearisation", [path], cam.id, _names(config))
    fit = functools.partial(_fit, config, cam, path, out, echo)
    return run_keyed(store, out, stage, lambda: store.linearisation(cam.id), fit)


def _fit(
    config: SessionConfig, cam: CameraConfig, path: Path, out: Path, echo: Echo
) -> Linearisation:
    """The linearisation of :func:`imported_linearisation`, fitted, written and said."""
    # every camera of the session is checked before any file is written
    cv = read_cameras_toml(path, config.camera_ids, _names(config))[cam.id]
    if cam.size_px is not None and tuple(cam.size_px) != tuple(cv.size_px):
        raise InputError(
            f"{path}: camera {cam.id} is {cv.size_px[0]} x {cv.size_px[1]} pixels there, "
            f"{cam.size_px[0]} x {cam.size_px[1]} in session.toml"
        )
    region = read_fit_regions(path, config.camera_ids, _names(config))[cam.id]
    imported, rms = camera_from_opencv(cv, region_px=region)
    lin = imported.linearisation
    doc = linearisation_to_dict(lin, cam.id)
    doc["source"] = f"{path.name}: OpenCV distortions = {cv.lens.tolist()}"
    doc["fit_rms_px"] = rms  # polynomial (and L12..L16) vs OpenCV's undistortion
    write_text(out, json.dumps(doc, indent=2) + "\n")
    echo(f"  linearise {cam.id}: polynomial fitted to {path.name}'s lens, rms {rms:.4f} px")
    if rms > POLY_FIT_WARN_PX:
        echo(
            f"  warning: {cam.id}: the 4th-order polynomial follows {path.name}'s lens only "
            f"to {rms:.3f} px rms over the image (a strong lens)"
        )
    return lin


def _write(inputs: RouteInputs, files: dict[str, DltFile], method: str, source: Path) -> dict:
    summary: dict[str, Any] = {}
    for cam in inputs.cameras:
        L = files[cam.id].L  # taken as it is: no control points (rms NaN)
        result = dlt_result(L, method, files[cam.id].lens, np.zeros((0, 2)), hatze_violation(L))
        write_dlt_json(
            inputs.store.dlt_path(cam.id),
            cam.id,
            result,
            extra={"source": str(source.relative_to(inputs.root))},
        )
        summary[cam.id] = result
        inputs.echo(
            f"  calibrate {cam.id}: {method} from {source.name}, "
            f"centre {np.round(result.centre_mm).tolist()} mm"
        )
    return summary


def calibrate_from_cameras(inputs: RouteInputs) -> dict[str, DltResult]:
    """Each camera's DLT from the ``K [R | t]`` of ``[calibration] cameras``."""
    path = _source(inputs.config, "cameras")
    cvs = read_cameras_toml(path, [c.id for c in inputs.cameras], _names(inputs.config))
    regions = read_fit_regions(path, [c.id for c in inputs.cameras], _names(inputs.config))
    imported = {c: camera_from_opencv(cv, region_px=regions[c])[0] for c, cv in cvs.items()}
    files = {c: DltFile(c, m.dlt, lens=m.kolahi) for c, m in imported.items()}
    return _write(inputs, files, "cameras", path)


def calibrate_from_dltdv(inputs: RouteInputs) -> dict[str, DltResult]:
    """Each camera's DLT from ``[calibration] dlt`` (DLTdv8's pixel convention): columns
    named by a header row, or in session order."""
    path = _source(inputs.config, "dlt")
    try:
        files = read_dltdv_csv(path)
    except KisscalError as exc:
        if "no header row" not in str(exc):
            raise
        files = read_dltdv_csv(path, inputs.config.camera_ids)
    names = _names(inputs.config)
    unknown = [n for n in names if n not in files]
    if unknown:
        raise InputError(
            f"{path}: calibration.names maps {unknown[0]!r}, which is not a camera of this "
            f"file (it has {', '.join(files)})"
        )
    files = {names.get(c, c): dlt for c, dlt in files.items()}
    missing = [c.id for c in inputs.cameras if c.id not in files]
    if missing:
        raise InputError(f"{path}: no coefficients for camera {', '.join(missing)}")
    return _write(inputs, files, "dltdv", path)
