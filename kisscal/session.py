"""Runs a lab session: one stage calling the next, reading and writing through :mod:`kisscal.io`.

The CLI is a thin layer over the functions here; tests call them directly.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from kisscal.errors import NotBuiltError

Echo = Callable[[str], object]


def _quiet(_: str) -> None:
    return None


def synthesise(out: Path, *, echo: Echo = _quiet, **options: object) -> Path:
    """Write a synthetic KISS-like session to ``out``."""
    raise NotBuiltError("synth", "synthetic rig")


def demo(out: Path, *, seed: int = 1, echo: Echo = _quiet) -> None:
    """Synthesise a KISS-like session into ``out`` and process it."""
    raise NotBuiltError("demo", "synthetic rig")
