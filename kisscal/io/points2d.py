"""Reading and writing ``out/trials/<trial>/points2d.csv``: a trial's 2D input, for other
triangulators (DESIGN.md, contract version 3).

Columns: ``camera,field,x_px,y_px,point,weight``, one row per 2D observation kisscal
reconstructed the trial from: raw pixels, the ``points3d.csv`` row it went into and the
per-camera weight (1 / depth, m) that makes an algebraic DLT triangulator minimise image
distances, as kisscal's does (Woltring & Huiskes 1990, sec. 3). Each column is described
in ``docs/outputs/points3d.md``. Files written before ``weight`` read with NaN weights.

References
----------
Woltring, H. J., & Huiskes, R. (1990). Stereophotogrammetry. In Biomechanics of Human
Movement: Applications in Rehabilitation, Sports and Ergonomics.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points
from kisscal.errors import InputError
from kisscal.io.files import read_text, write_text

COLUMNS = ("camera", "field", "x_px", "y_px", "point", "weight")
#: The header of files written before ``weight`` (read with NaN weights).
_COLUMNS_V1 = COLUMNS[:5]


@dataclass(frozen=True)
class Points2DFile:
    """Contents of a points2d.csv.

    Attributes
    ----------
    camera : ndarray of str, shape (n,)
    field : ndarray of int, shape (n,)
    xy_px : ndarray, shape (n, 2)
        Raw pixel coordinates.
    point : ndarray of int, shape (n,)
        Row of points3d.csv the observation went into, -1 when unused.
    weight : ndarray, shape (n,)
        1 / depth (m) of that point in the camera; NaN when unused.
    """

    camera: NDArray[np.str_]
    field: NDArray[np.int64]
    xy_px: NDArray[np.float64]
    point: NDArray[np.int64]
    weight: NDArray[np.float64]


def observation_points(blob_row: ArrayLike, n_obs: int) -> NDArray[np.int64]:
    """The 3D point each of ``n_obs`` 2D observations went into (-1: none), from the
    (n_points, n_cameras) table of observation rows per point
    (:attr:`kisscal.recon.Points3D.blob_row`). A blob that two points share (two
    markers merged into one blob, :mod:`kisscal.recon.deblend`) goes to the first.

    Examples
    --------
    >>> observation_points([[0, -1, 2], [3, 4, -1]], 6)
    array([ 0, -1,  0,  1,  1, -1])
    """
    blob_row = np.asarray(blob_row, dtype=np.int64)
    n_points = len(blob_row)
    point = np.full(n_obs, n_points, dtype=np.int64)
    used = blob_row >= 0
    np.minimum.at(point, blob_row[used], np.nonzero(used)[0])
    point[point == n_points] = -1
    return point


def write_points2d(
    path: str | Path,
    camera_ids: tuple[str, ...] | list[str],
    camera: ArrayLike,
    field: ArrayLike,
    xy_px: ArrayLike,
    point: ArrayLike,
    weight: ArrayLike | None = None,
) -> Path:
    """Write a points2d.csv (see module docstring); ``camera`` holds indices into
    ``camera_ids``, ``weight`` the inverse depths in 1/m (NaN or omitted: empty).
    Returns the path written."""
    camera = np.asarray(camera, dtype=np.int64)
    field = np.asarray(field, dtype=np.int64)
    xy = as_points(xy_px, 2, "xy_px")
    point = np.asarray(point, dtype=np.int64)
    weight = np.full(len(point), np.nan) if weight is None else np.asarray(weight, dtype=float)
    if not (len(camera) == len(field) == len(xy) == len(point) == len(weight)):
        raise InputError("points2d: columns of different lengths")
    names = np.asarray(list(camera_ids) or [""], dtype=str)
    # formatted column by column (numpy's string ops), not row by row
    cells = [
        names[camera],
        np.char.mod("%d", field),
        np.char.mod("%.6f", xy[:, 0]),
        np.char.mod("%.6f", xy[:, 1]),
        np.where(point >= 0, np.char.mod("%d", point), ""),
        np.where(np.isfinite(weight), np.char.mod("%.9g", weight), ""),
    ]
    lines = cells[0]
    for column in cells[1:]:
        lines = np.char.add(np.char.add(lines, ","), column)
    text = ",".join(COLUMNS) + "\n" + "".join(line + "\n" for line in lines.tolist())
    path = Path(path)
    write_text(path, text)
    return path


def read_points2d(path: str | Path) -> Points2DFile:
    """Read a points2d.csv written by :func:`write_points2d` (camera ids kept as text,
    ``01`` stays ``01``)."""
    path = Path(path)
    rows = list(csv.reader(read_text(path).splitlines()))
    if not rows or tuple(rows[0]) not in (COLUMNS, _COLUMNS_V1):
        raise InputError(f"{path}: header must be {','.join(COLUMNS)}")
    try:
        body = np.array(rows[1:], dtype=str).reshape(-1, len(rows[0]))
        field = body[:, 1].astype(np.int64)
        xy = body[:, 2:4].astype(float)
        point = np.where(body[:, 4] == "", "-1", body[:, 4]).astype(np.int64)
        weight = np.where(body[:, 5] == "", "nan", body[:, 5]) if body.shape[1] > 5 else "nan"
        weight = np.broadcast_to(np.asarray(weight, dtype=float), field.shape).copy()
    except ValueError:
        raise InputError(
            f"{path}: ragged rows, or text in field, x_px, y_px, point, weight"
        ) from None
    return Points2DFile(body[:, 0], field, xy, point, weight)
