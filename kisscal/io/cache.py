"""The stage cache under ``out/cache/``: results keyed by a hash of inputs and parameters.

A stage's output is reused only when the key stored beside it matches the key of the
current inputs and parameters. The key file is written after the output (both
atomically), so an interrupted run can never pair an old key with a new output or the
other way round.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.detect.blobs import Blobs
from kisscal.io.files import atomic_path, write_text


def _canonical(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {type(obj).__name__: _canonical(dataclasses.asdict(obj))}
    if isinstance(obj, dict):
        return {str(k): _canonical(v) for k, v in sorted(obj.items(), key=lambda kv: str(kv[0]))}
    if isinstance(obj, (list, tuple)):
        return [_canonical(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return hashlib.sha256(np.ascontiguousarray(obj).tobytes()).hexdigest() + str(obj.shape)
    if isinstance(obj, Path):
        st = obj.stat()
        return [str(obj), st.st_size, st.st_mtime_ns]
    if isinstance(obj, (np.generic,)):
        return obj.item()
    return obj


def cache_key(*parts: Any) -> str:
    """A short hash of ``parts`` (dataclasses, arrays, file paths by size and mtime, ...)."""
    text = json.dumps(_canonical(list(parts)), sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:20]


def is_current(output: Path, key: str) -> bool:
    """True when ``output`` exists and was written for ``key``."""
    key_file = output.with_name(output.name + ".key")
    return output.exists() and key_file.is_file() and key_file.read_text().strip() == key


def mark_current(output: Path, key: str) -> None:
    """Record that ``output`` (already written) belongs to ``key``."""
    write_text(output.with_name(output.name + ".key"), key + "\n")


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
