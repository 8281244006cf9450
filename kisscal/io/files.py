"""Atomic file writing and long-format CSV tables.

Every output is written to a temporary file in the same folder and moved into place
with :func:`os.replace`, so a crash never leaves a half-written file that a later run
would trust.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.errors import InputError, MissingDataError


@contextlib.contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; move it onto ``path`` if the block succeeds."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # the temporary file keeps the target's extension: some writers (ezc3d) add one otherwise
    fd, tmp = tempfile.mkstemp(
        prefix=f".{path.name}.", suffix=f".part{path.suffix}", dir=path.parent
    )
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o644)  # mkstemp makes files private; outputs are ordinary files
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


@contextlib.contextmanager
def staged_folder(out: Path, force: bool = False) -> Iterator[Path]:
    """Yield a temporary folder beside ``out``; it replaces ``out`` if the block succeeds.

    The folder analogue of :func:`atomic_path`: a session written in the block appears
    whole or not at all. ``out`` may be missing or an empty folder; a non-empty one only
    with ``force``.
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise InputError(f"{out}: folder is not empty (use --force to overwrite it)")
    out.parent.mkdir(parents=True, exist_ok=True)
    root = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        yield root
        if out.exists():
            shutil.rmtree(out)
        root.rename(out)
    finally:
        if root.exists():
            shutil.rmtree(root, ignore_errors=True)


def write_bytes(path: Path, data: bytes) -> None:
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def write_text(path: Path, text: str) -> None:
    write_bytes(path, text.encode("utf-8"))


def write_csv(
    path: Path, header: Iterable[Any] | None, rows: Iterable[Iterable[Any]], eol: str = "\r\n"
) -> Path:
    """Write CSV rows (after ``header``, when given) atomically, lines ending in ``eol``."""
    with atomic_path(path) as tmp, tmp.open("w", newline="") as fh:
        writer = csv.writer(fh, lineterminator=eol)
        if header is not None:
            writer.writerow(header)
        writer.writerows(rows)
    return Path(path)


def read_text(path: str | Path, what: str = "file") -> str:
    """The text of a file (UTF-8; a byte-order mark, as Notepad writes, is dropped, and
    Windows or old Mac line ends read as ``\\n``).

    Raises
    ------
    MissingDataError
        There is no such file (the message says ``<path>: <what> not found``).
    InputError
        The file is not UTF-8 text or cannot be read.
    """
    path = Path(path)
    try:
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise MissingDataError(f"{path}: {what} not found") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({exc.strerror})") from None


def read_json(path: Path) -> Any:
    """A JSON file, or None when there is none.

    Raises
    ------
    InputError
        The file is there but is not JSON.
    """
    if not path.is_file():
        return None
    try:
        return json.loads(read_text(path))
    except json.JSONDecodeError as exc:
        raise InputError(f"{path}: not valid JSON ({exc.msg}, line {exc.lineno})") from None


def lookup(doc: Any, *keys: str) -> Any:
    """``doc[k1][k2]...`` of a JSON document, None where a level is missing or not a table.

    Examples
    --------
    >>> lookup({"a": {"b": 1}}, "a", "b"), lookup({"a": 1}, "a", "b")
    (1, None)
    """
    for key in keys:
        doc = doc.get(key) if isinstance(doc, Mapping) else None
    return doc


def write_json(path: Path, obj: object) -> None:
    write_text(path, json.dumps(obj, indent=2, default=_json_default) + "\n")


def _json_default(obj: object) -> object:
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot write {type(obj).__name__} to JSON")


def _format(value: object) -> str:
    if isinstance(value, (float, np.floating)):
        if not np.isfinite(value):
            return ""
        return f"{value:.6f}".rstrip("0").rstrip(".") if value != 0 else "0"
    if isinstance(value, (bool, np.bool_)):
        return "1" if value else "0"
    return str(value)


def table_to_csv(columns: Mapping[str, object]) -> str:
    """Format equal-length columns as CSV text (floats to 1e-6, NaN as empty)."""
    names = list(columns)
    arrays = [np.asarray(columns[n]) for n in names]
    lengths = {len(a) for a in arrays}
    if len(lengths) > 1:
        raise ValueError(
            f"columns differ in length: {dict(zip(names, map(len, arrays), strict=True))}"
        )
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(names)
    for row in zip(*arrays, strict=True):
        writer.writerow([_format(v) for v in row])
    return buf.getvalue()


def write_table(path: Path, columns: Mapping[str, object]) -> None:
    """Write a long-format table atomically."""
    write_text(path, table_to_csv(columns))


def read_table(
    path: Path, required: tuple[str, ...] = (), numeric: tuple[str, ...] = ()
) -> dict[str, np.ndarray]:
    """Read a CSV table into columns (numeric columns as float arrays, others as str).

    Raises :class:`KisscalError` naming the file when it is missing, empty, lacks a
    ``required`` column, or holds text in a column named in ``numeric``. A byte-order mark
    and Windows line ends are accepted.
    """
    rows = list(csv.reader(io.StringIO(read_text(path))))
    if not rows:
        raise InputError(f"{path}: empty file, expected a header line")
    header, body = rows[0], rows[1:]
    missing = [c for c in required if c not in header]
    if missing:
        raise InputError(
            f"{path}: missing column(s) {', '.join(missing)}; found {', '.join(header)}"
        )
    bad = [i + 2 for i, r in enumerate(body) if len(r) != len(header)]
    if bad:
        raise InputError(f"{path}: line {bad[0]} has a different number of fields than the header")
    out: dict[str, np.ndarray] = {}
    for j, name in enumerate(header):
        col = [r[j] for r in body]
        try:
            out[name] = np.array([float(v) if v != "" else np.nan for v in col], dtype=float)
        except ValueError:
            if name in numeric:
                line = next(i + 2 for i, v in enumerate(col) if not _is_number(v))
                raise InputError(
                    f"{path}: line {line}: {name} must be a number, got {col[line - 2]!r}"
                ) from None
            out[name] = np.array(col, dtype=str)
    return out


def _is_number(text: str) -> bool:
    try:
        float(text or "nan")
    except ValueError:
        return False
    return True
