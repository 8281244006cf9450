"""Session configuration: ``session.toml`` (DESIGN.md, "Session on disk", version 1)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from kisscal.errors import KisscalError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def load_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file; a missing or malformed file is a :class:`KisscalError`."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise KisscalError(f"{path}: file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise KisscalError(f"{path}: not valid TOML ({exc})") from None
