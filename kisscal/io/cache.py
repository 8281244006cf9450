"""The blobs cache under ``out/cache/blobs/``: many frames' blobs in one ``.npz``.

Where the files go and when they are current is :class:`kisscal.io.store.SessionStore`'s.
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from kisscal.detect.blobs import Blobs
from kisscal.io.files import atomic_path

_BLOB_FIELDS = [f.name for f in dataclasses.fields(Blobs)]


def save_blob_frames(path: Path, frames: Sequence[Blobs]) -> None:
    """Store the blobs of many frames in one ``.npz`` (atomically)."""
    counts = np.array([len(b) for b in frames], dtype=np.int64)
    arrays = {
        name: np.concatenate([getattr(b, name) for b in frames]) if frames else np.zeros(0)
        for name in _BLOB_FIELDS
    }
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            np.savez(fh, counts=counts, **arrays)


def load_blob_frames(path: Path) -> list[Blobs]:
    """The frames stored by :func:`save_blob_frames`."""
    with np.load(path) as data:
        counts = data["counts"]
        arrays = {name: data[name] for name in _BLOB_FIELDS}
    edges = np.concatenate([[0], np.cumsum(counts)])
    return [
        Blobs(**{name: arrays[name][a:b] for name in _BLOB_FIELDS})
        for a, b in itertools.pairwise(edges)
    ]
