"""What every session stage shares: the config, the output folder, cache-key parts, figures."""

from __future__ import annotations

import difflib
import importlib
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from kisscal.errors import KisscalError
from kisscal.grid import Linearisation
from kisscal.io.config import CameraConfig, SessionConfig, load_session


def out_dir(root: Path) -> Path:
    """The folder every output of the session at ``root`` goes to."""
    return Path(root) / "out"


def load_config(root: Path) -> SessionConfig:
    """The validated ``session.toml`` of the session at ``root``."""
    return load_session(Path(root))


def select_cameras(config: SessionConfig, camera: str | None) -> tuple[CameraConfig, ...]:
    """Every camera, or only ``camera`` (an unknown id is an error with a did-you-mean)."""
    if camera is None:
        return config.cameras
    for cam in config.cameras:
        if cam.id == camera:
            return (cam,)
    close = difflib.get_close_matches(camera, list(config.camera_ids), n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    raise KisscalError(f"no camera {camera!r} in {config.path}{hint}")


def file_keys(paths: Sequence[Path], root: Path) -> list[tuple[str, int, int]]:
    """Input files for a cache key: path inside the session, size and modification time.

    Paths are relative so that a copied or moved session keeps its cache.
    """
    keys = []
    for p in paths:
        st = Path(p).stat()
        keys.append((Path(p).relative_to(root).as_posix(), st.st_size, st.st_mtime_ns))
    return keys


def linearisation_key(lins: Mapping[str, Linearisation]) -> dict[str, tuple]:
    """What of each camera's linearisation a cache key depends on."""
    return {c: (lin.x, lin.y, lin.center_px, lin.scale_px) for c, lin in lins.items()}


def figure(root: Path, name: str, module: str, function: str, *args: Any) -> None:
    """Draw a stage figure into ``out/figures/<name>.png``.

    The drawing module is imported only here, so that a session run without figures
    never imports matplotlib. A figure that cannot be drawn (e.g. a degenerate trial) is
    skipped: figures illustrate the numbers, which are already written.
    """
    from kisscal.report.html import save_figure

    draw = getattr(importlib.import_module(module), function)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            save_figure(draw(*args), out_dir(root) / "figures" / f"{name}.png")
    except (ValueError, IndexError):
        return
