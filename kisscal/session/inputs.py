"""What every session stage shares: the config, the write lock, figures."""

from __future__ import annotations

import dataclasses
import difflib
import functools
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from kisscal.errors import InputError, KisscalError, MissingDataError
from kisscal.io.config import CameraConfig, SessionConfig, load_session
from kisscal.io.frames import camera_frames
from kisscal.io.lock import session_lock
from kisscal.io.store import SessionStore
from kisscal.session.figures import drawing_beside, submit_figure

F = TypeVar("F", bound=Callable[..., Any])


def loads_config(func: F) -> F:
    """Call ``func(root, ..., config=...)`` with the session's config: the caller's when it
    has it loaded (a stage the runner calls), else :func:`load_config`'s. The one place a
    command reads ``session.toml``, so a command reads it once and hands it down."""

    @functools.wraps(func)
    def loaded(root: Path, *args: Any, config: SessionConfig | None = None, **kwargs: Any) -> Any:
        return func(root, *args, config=config or load_config(Path(root)), **kwargs)

    return loaded  # type: ignore[return-value]


def writes_session(func: F) -> F:
    """Run ``func(root, ..., config=...)`` holding the session's write lock (see
    :mod:`kisscal.io.lock`), the config read first (:func:`loads_config`): a missing or bad
    ``session.toml`` is said before the lock makes ``out/``, never a folder for a typo."""

    @functools.wraps(func)
    def locked(root: Path, *args: Any, **kwargs: Any) -> Any:
        with session_lock(SessionStore(root).out), drawing_beside():
            return func(root, *args, **kwargs)

    return loads_config(locked)


def load_config(root: Path) -> SessionConfig:
    """The validated ``session.toml`` of the session at ``root``, every camera's size known.

    A camera whose ``size`` is left out of ``[[cameras]]`` takes the size of its first
    frame (grid, rods, axes, calibration or trial images, in that order).
    """
    config = load_session(Path(root))
    if all(c.size_px is not None for c in config.cameras) or not image_sources(config):
        return config  # without any images a size is neither knowable nor needed
    cameras = tuple(
        c if c.size_px is not None else CameraConfig(c.id, _first_frame_size(config, c.id))
        for c in config.cameras
    )
    return dataclasses.replace(config, cameras=cameras)


def needs_calibration(config: SessionConfig) -> bool:
    """False for a session of C3D trials only and no calibration inputs: nothing to
    linearise or calibrate (its 3D points come calibrated)."""
    given = config.rods or config.calibration or config.wand or config.grid
    return bool(given) or any(t.source != "c3d" for t in config.trials)


def image_sources(config: SessionConfig) -> list[tuple[str, str, bool, str | None]]:
    """Every set of frames of the session: (what, path pattern, is a video, field order).

    Any set may be a video (a pattern with a video suffix), and any may be interlaced.
    """
    sources = []
    if config.grid is not None:
        sources.append(("grid", config.grid.images, False, config.grid.fields))
    if config.rods is not None:
        sources.append(("rod", config.rods.images, False, config.rods.fields))
    if config.axes is not None:
        sources.append(("axes", config.axes.images, False, config.axes.fields))
    cal = config.calibration
    if cal is not None and cal.images:
        sources.append(("calibration", cal.images, False, cal.fields))
    for t in config.trials:
        if t.images or t.video:
            pattern = t.images or t.video or ""
            sources.append((f"trial {t.name!r}", pattern, bool(t.video), t.fields))
    return sources


def _first_frame_size(config: SessionConfig, camera: str) -> tuple[int, int]:
    for what, pattern, video, fields in image_sources(config):
        try:
            frames = camera_frames(config.root, pattern, camera, what, video, fields)
        except KisscalError:
            continue
        if len(frames):
            h, w = frames[0].shape[:2]
            return int(w), int(h)
    hint = "; ".join(
        h for _w, pattern, _v, _f in image_sources(config) if (h := folders_hint(config, pattern))
    )
    raise MissingDataError(
        f"{config.path}: camera {camera} has no size and no images to take it from; "
        f"give size = [width, height] in its [[cameras]] entry{'; ' + hint if hint else ''}"
    )


def folders_hint(config: SessionConfig, pattern: str) -> str:
    """What is in the folder that should hold a folder per camera, when none of its
    folders is named after a camera id (``""`` otherwise, or when there is no such folder).

    ``trials/walk01/{camera}/*.png`` with folders ``A``, ``B`` instead of ``cam1``,
    ``cam2`` gives one line naming ``A``, ``B`` and the ids, where each camera alone would
    only say its images are missing.
    """
    head, sep, _tail = pattern.partition("{camera}")
    if not sep or not head.endswith("/"):
        return ""
    folder = config.root / head
    there = sorted(p.name for p in folder.iterdir() if p.is_dir()) if folder.is_dir() else []
    if not there or set(there) & set(config.camera_ids):
        return ""
    shown = ", ".join(there[:8]) + (f" and {len(there) - 8} more" if len(there) > 8 else "")
    return (
        f"{folder} holds folders {shown}, none named after a camera id "
        f"({', '.join(config.camera_ids)}): rename them, or change the ids in [[cameras]]"
    )


def select_cameras(config: SessionConfig, camera: str | None) -> tuple[CameraConfig, ...]:
    """Every camera, or only ``camera`` (an unknown id is an error with a did-you-mean)."""
    if camera is None:
        return config.cameras
    for cam in config.cameras:
        if cam.id == camera:
            return (cam,)
    close = difflib.get_close_matches(camera, list(config.camera_ids), n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    raise InputError(f"no camera {camera!r} in {config.path}{hint}")


def figure(root: Path, name: str, draw: Callable[..., Any], *args: Any) -> None:
    """Draw a stage figure, ``draw(*args)``, into ``out/figures/<name>.png`` (beside the
    stage when a session command runs, see :mod:`kisscal.session.figures`).

    The drawing functions import matplotlib only when they draw, so that a session run
    without figures never imports it.
    """
    submit_figure(SessionStore(root).figure_path(name), draw, args)
