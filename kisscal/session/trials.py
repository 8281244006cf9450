"""The session's blobs: each camera's frames (a trial's, or a static object's) detected
with that camera's settings and cached, and a trial's 2D data for the stages that take
it: the raw blob centroids of every field per camera, detected in the trial's images or
video or read from centroid files, and the files they come from (for cache keys)."""

from __future__ import annotations

import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kisscal.detect import Blobs, DetectionParams, ImageJob, detect_jobs
from kisscal.errors import InputError, KisscalError, MissingDataError
from kisscal.io.cache import save_blob_frames
from kisscal.io.config import SessionConfig, TrialConfig
from kisscal.io.files import read_table
from kisscal.io.frames import frame_name, source_files, trial_frames
from kisscal.io.store import SessionStore
from kisscal.session.progress import Echo, counted, quiet

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
    size_px: tuple[int, int]

    def __len__(self) -> int:
        return len(self.frames)

    def __getitem__(self, index):  # type: ignore[override]
        image = self.frames[index]
        h, w = image.shape[:2]
        if (w, h) != tuple(self.size_px):
            raise InputError(
                f"{frame_name(self.frames, index)}: {w} x {h} pixels, but camera "
                f"{self.camera}'s frames are "
                f"{self.size_px[0]} x {self.size_px[1]}"
            )
        return image

    @property
    def sequential(self) -> bool:
        return bool(getattr(self.frames, "sequential", False))


def chunk_size(frames: Sequence, workers: int | None) -> int:
    """Consecutive frames a detection worker takes at a time: 32, or for a video (decoded
    in order) an even share of the whole, so that each worker seeks once."""
    n_workers = max(workers or os.cpu_count() or 1, 1)
    if not getattr(frames, "sequential", False):
        return 32
    share = -(-len(frames) // n_workers)
    return max(share + share % 2, 2)  # even: both fields of a frame go to one worker


def camera_blobs(
    root: Path,
    config: SessionConfig,
    frames: Mapping[str, Sequence[np.ndarray]],
    detection: Mapping[str, DetectionParams],
    fields: str | None,
    name: tuple[str, str],
    echo: Echo = quiet,
    workers: int | None = None,
) -> dict[str, list[Blobs]]:
    """Blobs of every frame of each camera's ``frames``, from the cache when it is current.

    The cameras whose cache is stale are detected together, in one pool of processes
    (:func:`kisscal.detect.detect_jobs`): the workers decode and detect, and no core
    waits for the last frames of one camera before the next camera starts. ``name`` is
    ``(cache stem, label)``: caches are ``out/cache/blobs/<stem>-<camera>.npz`` and
    messages say ``detect <label>``. A frame that cannot be read fails after the other
    cameras' blobs are cached.
    """
    stem, label = name
    sizes = {c.id: c.size_px for c in config.cameras}
    out: dict[str, list[Blobs]] = {}
    stale = []
    store = SessionStore(config.root)
    for cam, seq in frames.items():
        key = store.key("detect", source_files(seq), fields, detection[cam])
        cache = store.blobs_cache(stem, cam)
        if store.is_current(cache, key):
            out[cam] = store.blobs(stem, cam)
        else:
            stale.append((cam, SizedFrames(seq, cam, sizes[cam]), cache, key))
    if out:
        echo(f"  detect {label}: {len(out)} of {len(frames)} cameras cached")
    jobs = [
        ImageJob(s.__getitem__, len(s), detection[cam], chunk_size(s, workers))
        for cam, s, _cache, _key in stale
    ]
    t0 = time.perf_counter()
    failed: KisscalError | None = None
    for j, found in counted(detect_jobs(jobs, workers), f"detect {label}", len(jobs)):
        cam, _s, cache, key = stale[j]
        if isinstance(found, KisscalError):
            failed = failed or found
            continue
        save_blob_frames(cache, found)
        store.mark_current(cache, key)
        out[cam] = found
    if failed is not None:
        raise failed
    if stale:
        n = sum(len(s) for _cam, s, _cache, _key in stale)
        seconds = time.perf_counter() - t0
        echo(
            f"  detect {label}: {len(stale)} cameras, {n} frames in {seconds:.1f} s "
            f"({n / max(seconds, 1e-9):.0f} frames/s)"
        )
    return {cam: out[cam] for cam in frames}


def trial_input_files(config: SessionConfig, trial: TrialConfig) -> dict[str, list[Path]]:
    """Per camera, the files a trial's 2D data come from (for cache keys)."""
    if trial.source == "centroids":
        paths = {
            c: [config.root / trial.centroids.replace("{camera}", c)] for c in config.camera_ids
        }
    else:
        frames = _frames(config, trial)
        paths = {c: source_files(f) for c, f in frames.items()}
    for c, ps in paths.items():
        for p in ps:
            if not p.is_file():
                raise MissingDataError(f"{p}: file of trial {trial.name!r}, camera {c}, not found")
    return paths


def trial_blobs(
    root: Path,
    config: SessionConfig,
    trial: TrialConfig,
    detection: dict[str, DetectionParams],
    echo: Echo,
    workers: int | None = None,
) -> dict[str, list[NDArray]]:
    """Per camera, the raw (distorted) valid blob centroids of every field, as (n, 2) arrays.

    ``detection`` holds each camera's detection parameters (unused for centroid files).
    """
    if trial.source == "centroids":
        return _centroid_files(config, trial)
    frames = _frames(config, trial)
    name = (f"trial-{trial.name}", trial.name)
    blobs = camera_blobs(root, config, frames, detection, trial.fields, name, echo, workers)
    return {cam: [b.valid_only().xy_px for b in found] for cam, found in blobs.items()}


def _frames(config: SessionConfig, trial: TrialConfig) -> dict[str, Any]:
    """Per camera, the frame sequence of an image or video trial."""
    return trial_frames(
        config.root,
        trial.images or trial.video or "",
        config.camera_ids,
        trial.name,
        video=trial.source == "video",
        fields=trial.fields,
    )


def _centroid_files(config: SessionConfig, trial: TrialConfig) -> dict[str, list[NDArray]]:
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
        off = (xy[:, 0] < -0.5) | (xy[:, 0] > w - 0.5) | (xy[:, 1] < -0.5) | (xy[:, 1] > h - 0.5)
        if off.any():
            row = int(np.argmax(off))
            raise InputError(
                f"{path}: row {row + 2} ({xy[row, 0]:g}, {xy[row, 1]:g}) lies outside the "
                f"{w} x {h} pixel image"
            )
