"""A trial's 2D sources: its frames per camera (images or video, each frame checked for
the camera's size when read), its centroid files, and the files they come from (for
cache keys). Their blobs are detected by the runner
(:func:`kisscal.session.runner.trial_blobs`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import in_image
from kisscal.errors import InputError, MissingDataError
from kisscal.io.config import SessionConfig, TrialConfig
from kisscal.io.files import read_table
from kisscal.io.frames import frame_name, source_files, trial_frames

#: Columns of a centroid file (``[[trials]] centroids``), raw pixel coordinates.
CENTROID_COLUMNS = ("field", "x_px", "y_px")


@dataclass(frozen=True)
class SizedFrames(Sequence):
    """A camera's frames, each checked for the camera's image size when it is read.

    A frame of another size among a camera's frames (a file from another camera, a
    resized export) would otherwise be detected in the wrong pixel frame and lost.
    """

    frames: Sequence[np.ndarray]
    camera: str
    size_px: tuple[int, int] | None

    def __len__(self) -> int:
        return len(self.frames)

    def __getitem__(self, index):  # type: ignore[override]
        image = self.frames[index]
        h, w = image.shape[:2]
        if self.size_px is not None and (w, h) != tuple(self.size_px):
            raise InputError(
                f"{frame_name(self.frames, index)}: {w} x {h} pixels, but camera "
                f"{self.camera}'s frames are "
                f"{self.size_px[0]} x {self.size_px[1]}"
            )
        return image

    @property
    def sequential(self) -> bool:
        return bool(getattr(self.frames, "sequential", False))


def trial_input_files(config: SessionConfig, trial: TrialConfig) -> dict[str, list[Path]]:
    """Per camera, the files a trial's 2D data come from (for cache keys)."""
    if trial.source != "centroids":  # frames are listed (or opened) only when they exist
        frames = trial_frames_of(config, trial)
        return {c: source_files(f) for c, f in frames.items()}
    paths = {c: config.root / trial.centroids.replace("{camera}", c) for c in config.camera_ids}
    for c, p in paths.items():
        if not p.is_file():
            raise MissingDataError(f"{p}: file of trial {trial.name!r}, camera {c}, not found")
    return {c: [p] for c, p in paths.items()}


def trial_frames_of(config: SessionConfig, trial: TrialConfig) -> dict[str, Any]:
    """Per camera, the frame sequence of an image or video trial."""
    pattern, video = trial.images or trial.video or "", trial.source == "video"
    return trial_frames(
        config.root, pattern, config.camera_ids, trial.name, video=video, fields=trial.fields
    )


def centroid_files(config: SessionConfig, trial: TrialConfig) -> dict[str, list[NDArray]]:
    """Centroids given per camera as ``field,x_px,y_px`` rows (raw pixels)."""
    out = {}
    for cam in config.cameras:
        path = config.root / trial.centroids.replace("{camera}", cam.id)
        table = read_table(path, required=CENTROID_COLUMNS, numeric=CENTROID_COLUMNS)
        f = table["field"].astype(float)
        xy = np.column_stack([table["x_px"], table["y_px"]]).astype(float)
        _check_centroids(path, f, xy, cam.size_px)
        f = f.astype(int)
        n = int(f.max()) + 1 if len(f) else 0
        out[cam.id] = [xy[f == i] for i in range(n)]
    n_fields = max(len(v) for v in out.values())
    return {c: v + [np.zeros((0, 2))] * (n_fields - len(v)) for c, v in out.items()}


def _check_centroids(
    path: Path, field: NDArray, xy: NDArray, size_px: tuple[int, int] | None
) -> None:
    """Refuse rows a camera cannot have seen: not numbers, negative fields, off the image."""
    bad = ~np.isfinite(xy).all(axis=1) | ~np.isfinite(field) | (field != np.round(field))
    if bad.any():
        raise InputError(
            f"{path}: row {int(np.argmax(bad)) + 2} has a field or centroid that is not a number"
        )
    if len(field) and field.min() < 0:
        raise InputError(f"{path}: field numbers must be 0 or more")
    if size_px is not None:
        w, h = size_px
        off = ~in_image(xy, size_px)
        if off.any():
            row = int(np.argmax(off))
            raise InputError(
                f"{path}: row {row + 2} ({xy[row, 0]:g}, {xy[row, 1]:g}) lies outside the "
                f"{w} x {h} pixel image"
            )
