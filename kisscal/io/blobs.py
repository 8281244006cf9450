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

from kisscal.detect.blobs import Blobs, flag_string
from kisscal.io.files import atomic_path

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
