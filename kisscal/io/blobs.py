"""The blob table CSV of DESIGN.md: ``image,x_px,y_px,pixels,w_px,h_px,valid,flags``.

One row per blob; ``image`` is the image path as the user gave it, ``valid`` is 0/1 and
``flags`` names the tests that touched the blob, joined by ``|`` (e.g. ``split_ul|too_large``).
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import TextIO

import numpy as np

from kisscal.detect.blobs import Blobs, flag_string, parse_flags
from kisscal.errors import InputError
from kisscal.io.files import atomic_path, read_text

COLUMNS = ("image", "x_px", "y_px", "pixels", "w_px", "h_px", "valid", "flags")


def blob_rows(tables: Iterable[tuple[str, Blobs]]) -> Iterator[tuple[object, ...]]:
    """The rows of the blob table (:data:`COLUMNS`), one per blob of each ``(image, blobs)``.

    Centroids are written with 4 decimals (0.1 milli-pixel, far below their accuracy).
    """
    for image, blobs in tables:
        for i in range(len(blobs)):
            yield (
                image,
                f"{blobs.x_px[i]:.4f}",
                f"{blobs.y_px[i]:.4f}",
                int(blobs.pixels[i]),
                int(blobs.w_px[i]),
                int(blobs.h_px[i]),
                int(bool(blobs.valid[i])),
                flag_string(int(blobs.flags[i])),
            )


def write_blobs(path: str | Path, tables: Iterable[tuple[str, Blobs]]) -> int:
    """Write ``(image, blobs)`` pairs to one CSV; return the number of rows written."""
    with atomic_path(Path(path)) as tmp, tmp.open("w", newline="") as f:
        return _write_rows(f, tables)


def format_blobs(tables: Iterable[tuple[str, Blobs]]) -> str:
    """The blob table as CSV text (what ``kisscal detect`` prints without ``--out``)."""
    buffer = io.StringIO()
    _write_rows(buffer, tables)
    return buffer.getvalue()


def _write_rows(f: TextIO, tables: Iterable[tuple[str, Blobs]]) -> int:
    out = csv.writer(f, lineterminator="\n")
    out.writerow(COLUMNS)
    n = 0
    for row in blob_rows(tables):
        out.writerow(row)
        n += 1
    return n


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
