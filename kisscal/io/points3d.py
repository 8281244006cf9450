"""Reading and writing ``out/trials/<trial>/points3d.csv``.

Columns: ``field,x_mm,y_mm,z_mm,n_cameras,rms_px`` (DESIGN.md, public contract) followed by
one ``blob_<camera>`` column per camera: the index of the blob, within that camera's blobs
of that field in the order of the 2D input, that the point was built from (-1: none).
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points
from kisscal.errors import InputError
from kisscal.io.files import read_text, write_csv
from kisscal.recon.reconstruct import Points3D

BASE_COLUMNS = ("field", "x_mm", "y_mm", "z_mm", "n_cameras", "rms_px")


@dataclass(frozen=True)
class Points3DFile:
    """Contents of a points3d.csv.

    Attributes
    ----------
    field : ndarray of int, shape (n,)
    xyz_mm : ndarray, shape (n, 3)
    n_cameras : ndarray of int, shape (n,)
    rms_px : ndarray, shape (n,)
    blob : ndarray of int, shape (n, n_cameras_total)
        Blob index within (field, camera) per camera, -1 where the camera was not used.
    camera_ids : tuple of str
        Camera of each ``blob`` column.
    """

    field: NDArray[np.int64]
    xyz_mm: NDArray[np.float64]
    n_cameras: NDArray[np.int64]
    rms_px: NDArray[np.float64]
    blob: NDArray[np.int64]
    camera_ids: tuple[str, ...]


def blob_index_in_field(field: ArrayLike, camera: ArrayLike) -> NDArray[np.int64]:
    """Index of each row of a long-format 2D table among its (field, camera) rows, in order."""
    field = np.asarray(field, dtype=np.int64)
    camera = np.asarray(camera, dtype=np.int64)
    order = np.lexsort((np.arange(len(field)), camera, field))
    key_f, key_c = field[order], camera[order]
    new = np.r_[True, (key_f[1:] != key_f[:-1]) | (key_c[1:] != key_c[:-1])]
    starts = np.flatnonzero(new)
    group_start = starts[np.cumsum(new) - 1]
    out = np.empty(len(field), dtype=np.int64)
    out[order] = np.arange(len(field)) - group_start
    return out


def write_points3d(
    path: str | Path,
    field: ArrayLike,
    xyz_mm: ArrayLike,
    n_cameras: ArrayLike,
    rms_px: ArrayLike,
    blob: ArrayLike,
    camera_ids: list[str] | tuple[str, ...],
) -> Path:
    """Write a points3d.csv (see module docstring); returns the path written.

    ``blob`` holds per-camera blob indices within the field (see :func:`blob_index_in_field`
    to turn :attr:`kisscal.recon.Points3D.blob_row` rows of the 2D table into them).
    """
    path = Path(path)
    field = np.asarray(field, dtype=np.int64)
    xyz = as_points(xyz_mm, 3, "xyz_mm")
    n_cam = np.asarray(n_cameras, dtype=np.int64)
    rms = np.asarray(rms_px, dtype=float)
    blob = np.asarray(blob, dtype=np.int64)
    # a trial without points is an empty table (header only): -1 cannot size its columns
    blob = blob.reshape(len(field), len(camera_ids) if blob.size == 0 else -1)
    if blob.shape[1] != len(camera_ids):
        raise InputError(f"points3d: {blob.shape[1]} blob columns for {len(camera_ids)} camera ids")
    if not (len(xyz) == len(n_cam) == len(rms) == len(field)):
        raise InputError("points3d: columns of different lengths")
    rows = (
        [int(f), f"{x:.4f}", f"{y:.4f}", f"{z:.4f}", int(n), f"{r:.4f}", *(int(b) for b in bs)]
        for f, (x, y, z), n, r, bs in zip(field, xyz, n_cam, rms, blob, strict=True)
    )
    return write_csv(path, [*BASE_COLUMNS, *(f"blob_{c}" for c in camera_ids)], rows, "\n")


def read_points3d(path: str | Path) -> Points3DFile:
    """Read a points3d.csv written by :func:`write_points3d` (blob columns optional)."""
    path = Path(path)
    rows = list(csv.reader(io.StringIO(read_text(path, "points3d file"))))
    if not rows or tuple(rows[0][: len(BASE_COLUMNS)]) != BASE_COLUMNS:
        raise InputError(f"{path}: header must start with {','.join(BASE_COLUMNS)}")
    header = rows[0]
    extra = header[len(BASE_COLUMNS) :]
    if any(not h.startswith("blob_") for h in extra):
        raise InputError(
            f"{path}: unexpected column(s) {[h for h in extra if not h.startswith('blob_')]}"
        )
    try:
        data = np.array(rows[1:], dtype=float).reshape(-1, len(header))
    except ValueError as exc:
        raise InputError(f"{path}: non-numeric or ragged rows") from exc
    return Points3DFile(
        field=data[:, 0].astype(np.int64),
        xyz_mm=data[:, 1:4],
        n_cameras=data[:, 4].astype(np.int64),
        rms_px=data[:, 5],
        blob=data[:, 6:].astype(np.int64),
        camera_ids=tuple(h.removeprefix("blob_") for h in extra),
    )


def write_trial_points(
    path: str | Path,
    points: Points3D,
    field: ArrayLike,
    camera: ArrayLike,
    camera_ids: list[str] | tuple[str, ...],
) -> Path:
    """Write the result of :func:`kisscal.recon.reconstruct_trial` for the 2D table
    (``field``, ``camera``) it was computed from."""
    index = blob_index_in_field(field, camera)
    row = points.blob_row
    blob = np.where(row >= 0, index[np.maximum(row, 0)], -1)
    return write_points3d(
        path, points.field, points.xyz_mm, points.n_cameras, points.rms_px, blob, camera_ids
    )
