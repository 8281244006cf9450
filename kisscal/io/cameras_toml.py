"""``cameras.toml`` (the anipose / Pose2Sim calibration layout) and OpenCV's YAML camera
files: written from, and read into, :class:`kisscal.camera.Camera` (OpenCV's model: zero
skew, Brown's lens, no polynomial).

One table per camera, named by the camera id, and a ``[metadata]`` table (units,
``fit_rms_px``, ``fit_region_px``, read back by :func:`read_fit_regions`) that both tools
skip: each key is described in ``docs/outputs/cameras.md``. Pose2Sim works in metres,
anipose in the unit of its calibration board: kisscal writes mm unless told otherwise
(``units``) and reads any (``metadata.units``, or metres when every camera lies within
100 units of the origin, as no lab camera does in mm). Tables may carry other names than
the session's camera ids (Pose2Sim's ``cam_01``, ...): ``names`` maps them on reading.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import tomli_w

from kisscal.camera import Camera
from kisscal.errors import InputError
from kisscal.io.files import atomic_path, write_text
from kisscal.io.toml_table import load_toml

#: Tables of a cameras.toml that are not cameras (anipose, Pose2Sim).
NOT_CAMERAS = ("metadata", "capture_volume", "charuco", "checkerboard")
CAMERA_KEYS = ("name", "size", "matrix", "distortions", "rotation", "translation")
#: Length units a cameras.toml may be written in, as millimetres per unit.
UNITS_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0}


def write_cameras_toml(
    path: str | Path,
    cameras: Sequence[Camera],
    metadata: Mapping[str, Any],
    *,
    units: str = "mm",
    names: Sequence[str] | None = None,
    k3: bool = True,
) -> Path:
    """Write a ``cameras.toml``: one table per camera (see the module docstring).

    ``units`` is the unit of ``translation`` (``mm``, ``cm`` or ``m``, also written as
    ``metadata.units``); ``names`` the table and ``name`` of each camera (default the
    camera's own); the distortion vector as the camera holds it (5, 8 or 12 coefficients),
    or with ``k3`` False four (``k1 k2 p1 p2``, Pose2Sim's layout; the cameras' ``k3`` and
    any higher terms must then be 0).
    """
    if units not in UNITS_MM:
        raise InputError(f"units must be one of {', '.join(UNITS_MM)}, got {units!r}")
    names = [c.id for c in cameras] if names is None else list(names)
    if len(names) != len(cameras) or len(set(names)) != len(names):
        raise InputError(f"{path}: need one distinct name per camera, got {names}")
    doc: dict[str, Any] = {}
    for name, cam in zip(names, cameras, strict=True):
        dist = np.asarray(cam.lens, dtype=float)
        if not k3 and np.any(dist[4:] != 0.0):
            raise InputError(f"{path}: camera {cam.id} has k3 = {dist[4]}; cannot drop it")
        doc[name] = {
            "name": name,
            "size": [int(cam.size_px[0]), int(cam.size_px[1])],
            "matrix": cam.K.tolist(),
            "distortions": (dist if k3 else dist[:4]).tolist(),
            "rotation": cv2.Rodrigues(cam.R)[0].ravel().tolist(),
            "translation": (cam.t / UNITS_MM[units]).tolist(),
            "fisheye": False,
        }
    doc["metadata"] = {**metadata, "units": units}
    write_text(Path(path), tomli_w.dumps(doc))
    return Path(path)


def _numbers(path: Path, table: str, key: str, value: Any, shape: tuple[int, ...]) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        arr = np.zeros(0)
    if arr.shape != shape or not np.isfinite(arr).all():
        want = " x ".join(str(s) for s in shape)
        raise InputError(f"{path}: [{table}] {key} must be {want} finite numbers")
    return arr


def _camera(path: Path, table: str, d: dict[str, Any], scale_mm: float) -> Camera:
    missing = [k for k in CAMERA_KEYS if k not in d]
    if missing:
        raise InputError(f"{path}: [{table}] is missing {', '.join(missing)}")
    if d.get("fisheye", False):
        raise InputError(f"{path}: [{table}] is a fisheye camera; kisscal reads pinhole ones")
    dist = np.asarray(d["distortions"], dtype=float).ravel()
    if dist.size not in (4, 5, 8, 12):
        raise InputError(
            f"{path}: [{table}] distortions must be 4, 5, 8 or 12 numbers (OpenCV's "
            f"k1 k2 p1 p2 [k3 [k4 k5 k6 [s1 s2 s3 s4]]]), got {dist.size}"
        )
    matrix = _numbers(path, table, "matrix", d["matrix"], (3, 3))
    size = _numbers(path, table, "size", d["size"], (2,))
    rotation = _numbers(path, table, "rotation", d["rotation"], (3,)).ravel()
    return Camera(
        K=matrix,
        R=cv2.Rodrigues(rotation)[0],
        t=_numbers(path, table, "translation", d["translation"], (3,)) * scale_mm,
        lens=np.r_[dist, np.zeros(max(0, 5 - dist.size))],
        id=str(d["name"]),
        size_px=(int(size[0]), int(size[1])),
    )


def _units_mm(path: Path, doc: dict[str, Any], tables: dict[str, dict]) -> float:
    units = doc.get("metadata", {}).get("units") if isinstance(doc.get("metadata"), dict) else None
    if units is not None:
        if units not in UNITS_MM:
            raise InputError(f"{path}: metadata.units must be mm, cm or m, got {units!r}")
        return UNITS_MM[units]
    reach = max(
        np.linalg.norm(np.asarray(t.get("translation", [0]), float)) for t in tables.values()
    )
    return 1000.0 if reach < 100.0 else 1.0


def read_cameras_toml(
    path: str | Path, camera_ids: Sequence[str], names: Mapping[str, str] | None = None
) -> dict[str, Camera]:
    """The cameras of ``camera_ids`` from a cameras.toml, matched by ``name`` (or table name).

    ``names`` maps the file's camera names to session ids (``{"cam_01": "cam1"}``); a
    session camera it does not name is looked up under its own id. The cameras returned
    carry the session ids.

    Raises
    ------
    KisscalError
        A camera of the session missing from the file, a name of ``names`` not in it, a
        missing key, a malformed value.
    """
    path = Path(path)
    doc, tables, keys = _camera_tables(path, camera_ids, names)
    scale = _units_mm(path, doc, tables)
    return {
        cam: dataclasses.replace(_camera(path, key, tables[key], scale), id=cam)
        for cam, key in keys.items()
    }


def read_fit_regions(
    path: str | Path, camera_ids: Sequence[str], names: Mapping[str, str] | None = None
) -> dict[str, tuple[float, float, float, float] | None]:
    """Where each camera's OpenCV model was fitted to follow a calibration:
    ``metadata.fit_region_px`` (``u_min, v_min, u_max, v_max``, raw px, by table name),
    which kisscal's export writes; None for a camera without one (other tools' files).

    Raises
    ------
    KisscalError
        As :func:`read_cameras_toml`, and a region that is not 4 finite numbers.
    """
    path = Path(path)
    doc, _, keys = _camera_tables(path, camera_ids, names)
    meta = doc.get("metadata") if isinstance(doc.get("metadata"), dict) else {}
    regions = meta.get("fit_region_px", {})
    if not isinstance(regions, dict):
        raise InputError(f"{path}: metadata.fit_region_px must be a table of camera regions")
    out: dict[str, tuple[float, float, float, float] | None] = {}
    for cam, key in keys.items():
        value = regions.get(key)
        if value is None:
            out[cam] = None
            continue
        box = _numbers(path, "metadata", f"fit_region_px.{key}", value, (4,))
        if np.any(box[2:] <= box[:2]):
            raise InputError(
                f"{path}: metadata.fit_region_px.{key} must be u0, v0, u1 > u0, v1 > v0"
            )
        out[cam] = (float(box[0]), float(box[1]), float(box[2]), float(box[3]))
    return out


def _camera_tables(
    path: Path, camera_ids: Sequence[str], names: Mapping[str, str] | None
) -> tuple[dict[str, Any], dict[str, dict], dict[str, str]]:
    """The file's document, its camera tables and the table of each session camera."""
    doc = load_toml(path)
    tables = {k: v for k, v in doc.items() if isinstance(v, dict) and k not in NOT_CAMERAS}
    if not tables:
        raise InputError(f"{path}: no camera tables")
    by_name = {str(t.get("name", k)): k for k, t in tables.items()}
    names = dict(names or {})
    unknown = [n for n in names if n not in by_name and n not in tables]
    if unknown:
        raise InputError(
            f"{path}: calibration.names maps {unknown[0]!r}, which is not a camera of this "
            f"file (it has {', '.join(sorted(by_name))})"
        )
    foreign = {sid: name for name, sid in names.items()}
    keys = {}
    for cam in camera_ids:
        name = foreign.get(cam, cam)
        key = by_name.get(name, name if name in tables else None)
        if key is None:
            raise InputError(
                f"{path}: no camera named {cam!r} (the file has {', '.join(sorted(by_name))}; "
                f"map them with [calibration] names = {{ {sorted(by_name)[0]} = "
                '"<camera id>", ... })'
            )
        keys[cam] = key
    return doc, tables, keys


def write_opencv_yaml(path: str | Path, cam: Camera, units: str = "mm") -> Path:
    """One camera as an OpenCV FileStorage YAML file (``cv::FileStorage`` reads it):
    ``image_width``, ``image_height``, ``camera_matrix``, ``distortion_coefficients``,
    ``rvec``, ``tvec`` (in ``units``: mm, cm or m) and ``units``."""
    if units not in UNITS_MM:
        raise InputError(f"units must be one of {', '.join(UNITS_MM)}, got {units!r}")
    path = Path(path)
    with atomic_path(path) as tmp:
        fs = cv2.FileStorage(str(tmp.with_suffix(".yml")), cv2.FILE_STORAGE_WRITE)
        fs.write("image_width", int(cam.size_px[0]))
        fs.write("image_height", int(cam.size_px[1]))
        fs.write("camera_matrix", np.asarray(cam.K, dtype=float))
        fs.write("distortion_coefficients", np.asarray(cam.lens, float).reshape(1, -1))
        fs.write("rvec", cv2.Rodrigues(cam.R)[0].reshape(3, 1))
        fs.write("tvec", cam.t.reshape(3, 1) / UNITS_MM[units])
        fs.write("units", units)
        fs.release()
        if tmp.with_suffix(".yml") != tmp:
            tmp.with_suffix(".yml").replace(tmp)
    return path
