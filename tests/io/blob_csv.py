"""Reading back the blob CSV that ``kisscal detect`` and the detection stage write
(kisscal.io.blobs): the package itself never reads it, the tests do, to check what was
written."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from kisscal.detect.blobs import Blobs, parse_flags
from kisscal.errors import InputError
from kisscal.io.blobs import COLUMNS
from kisscal.io.files import read_text


def read_blobs(path: str | Path) -> dict[str, Blobs]:
    """Read a blob CSV back into one :class:`Blobs` per image, in first-appearance order.

    The binary centroid is not stored in the file, so ``x_binary_px`` / ``y_binary_px``
    are NaN. Images without blobs do not appear (the file has no row for them).
    """
    path = Path(path)
    rows = list(csv.reader(io.StringIO(read_text(path, "blob file"))))
    if not rows or tuple(rows[0]) != COLUMNS:
        raise InputError(f"blobs: {path} does not start with the header {','.join(COLUMNS)}")
    by_image: dict[str, list[list[str]]] = {}
    for line, row in enumerate(rows[1:], start=2):
        if len(row) != len(COLUMNS):
            raise InputError(f"blobs: {path} line {line} has {len(row)} fields, expected 8")
        by_image.setdefault(row[0], []).append(row)
    tables: dict[str, Blobs] = {}
    for image, group in by_image.items():
        try:
            x = np.array([float(r[1]) for r in group])
            y = np.array([float(r[2]) for r in group])
            ints = np.array([[int(r[3]), int(r[4]), int(r[5]), int(r[6])] for r in group])
            flags = np.array([parse_flags(r[7]) for r in group], dtype=np.int64)
        except ValueError as exc:
            raise InputError(f"blobs: {path}, image {image}: {exc}") from exc
        nan = np.full(x.size, np.nan)
        tables[image] = Blobs(
            x_px=x,
            y_px=y,
            x_binary_px=nan,
            y_binary_px=nan.copy(),
            pixels=ints[:, 0].astype(np.int64),
            w_px=ints[:, 1].astype(np.int64),
            h_px=ints[:, 2].astype(np.int64),
            valid=ints[:, 3] != 0,
            flags=flags,
        )
    return tables
