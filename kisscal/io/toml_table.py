"""Reading ``session.toml``: the TOML file and a small helper per table being checked.

Every message names the file, the key (``cameras[1].size``) and what was expected, and
suggests the nearest known key for a misspelt one.
"""

from __future__ import annotations

import difflib
import sys
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.errors import InputError
from kisscal.io.files import read_text

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def load_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file; a missing or malformed file is a :class:`KisscalError`.

    A UTF-8 byte-order mark and Windows line ends are accepted (files saved by Notepad).
    """
    text = read_text(path)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: not valid TOML ({exc})") from None


def suggest(key: str, allowed: Iterable[str]) -> str:
    close = difflib.get_close_matches(key, sorted(allowed), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


@dataclass(frozen=True)
class Table:
    """One TOML table being parsed: where it sits (for messages) and its content."""

    path: Path
    where: str
    data: dict[str, Any]

    def fail(self, message: str) -> InputError:
        return InputError(f"{self.path}: {message}")

    def allow(self, allowed: Iterable[str]) -> Table:
        allowed = set(allowed)
        for key in self.data:
            if key not in allowed:
                raise self.fail(
                    f"unknown key {self.where}{key!r}{suggest(key, allowed)}; "
                    f"expected one of {', '.join(sorted(allowed))}"
                )
        return self

    def required(self, key: str) -> Any:
        if key not in self.data:
            raise self.fail(f"missing key {self.where}{key!r}")
        return self.data[key]

    def string(self, key: str, default: str | None = None) -> str | None:
        value = self.data.get(key, default)
        if value is None:
            return None
        if not isinstance(value, str) or not value.strip():
            raise self.fail(f"{self.where}{key} must be a non-empty string, got {value!r}")
        return value

    def number(self, key: str, default: Any = None, kind: type = float) -> Any:
        value = self.data.get(key, default)
        return number(self.path, f"{self.where}{key}", value, kind)

    def choice(self, key: str, choices: tuple[str, ...]) -> Any:
        value = self.data.get(key)
        if value is not None and value not in choices:
            raise self.fail(
                f"{self.where}{key} must be one of {', '.join(map(repr, choices))}, got {value!r}"
            )
        return value

    def points(self, key: str) -> np.ndarray:
        return points_mm(self.path, f"{self.where}{key}", self.required(key))

    def sub(self, key: str, index: int | None = None) -> Table:
        value = self.data[key] if index is None else self.data[key][index]
        where = f"{self.where}{key}." if index is None else f"{self.where}{key}[{index}]."
        if not isinstance(value, dict):
            raise self.fail(f"{where[:-1]} must be a table")
        return Table(self.path, where, value)

    def list_of_tables(self, key: str) -> list[Table]:
        value = self.data.get(key, [])
        if not isinstance(value, list):
            raise self.fail(f"{self.where}{key} must be a list of tables ([[{key}]])")
        return [self.sub(key, i) for i in range(len(value))]


def number(path: Path, where: str, value: Any, kind: type = float) -> Any:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise InputError(f"{path}: {where} must be a number, got {value!r}")
    if kind is int and int(value) != value:
        raise InputError(f"{path}: {where} must be a whole number, got {value!r}")
    if value <= 0:
        raise InputError(f"{path}: {where} must be positive, got {value!r}")
    return kind(value)


def points_mm(path: Path, where: str, value: Any) -> np.ndarray:
    try:
        pts = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{path}: {where} must be a list of [x, y, z] in mm") from None
    if pts.size == 0:
        raise InputError(f"{path}: {where} is empty; fill in [x, y, z] (mm) for each marker")
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
        raise InputError(
            f"{path}: {where} must be a list of [x, y, z] in mm, got shape {pts.shape}"
        )
    return pts


def unfilled_keys(value: Any, where: str = "") -> list[str]:
    """Where ``session.toml`` holds an empty list of coordinates (``points_mm = []``, as
    ``kisscal init`` writes them), named as the messages name keys (``rods.rod[0]...``)."""
    if isinstance(value, dict):
        named = f" ({value['name']})" if isinstance(value.get("name"), str) else ""
        found = []
        for key, item in value.items():
            path = f"{where}.{key}" if where else str(key)
            if key.endswith("_mm") and isinstance(item, list) and not item:
                found.append(f"{path}{named}")
            else:
                found += unfilled_keys(item, path)
        return found
    if isinstance(value, list):
        return [w for i, item in enumerate(value) for w in unfilled_keys(item, f"{where}[{i}]")]
    return []


def read_detection_table(path: Path) -> dict[str, Any]:
    """The ``[detection]`` table of a TOML file (a session.toml or a file of its own).

    Raises a one-line :class:`KisscalError` when the file has no such table.
    """
    data = load_toml(Path(path))
    table = data.get("detection")
    if not isinstance(table, dict):
        raise InputError(f"{path}: no [detection] table")
    return dict(table)
