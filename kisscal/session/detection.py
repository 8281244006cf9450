"""Blob detection for the session: cached per camera and image set, and ``kisscal detect``."""

from __future__ import annotations

import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from kisscal.detect import Blobs, DetectionParams, ImageJob, detect_jobs, detect_sequence
from kisscal.detect.configure import configure_detection
from kisscal.detect.pipeline import hopeless
from kisscal.errors import InputError, KisscalError
from kisscal.io.blobs import write_blobs
from kisscal.io.cache import save_blob_frames
from kisscal.io.config import SessionConfig
from kisscal.io.files import write_bytes
from kisscal.io.frames import frame_name, read_image, source_files
from kisscal.io.store import SessionStore
from kisscal.report.overlay import draw_overlay
from kisscal.session.configure import camera_detection
from kisscal.session.inputs import load_config, select_cameras, writes_session
from kisscal.session.params import Overrides, stage_params
from kisscal.session.progress import Echo, counted, quiet


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


def detect_images(
    paths: Sequence[Path],
    out_csv: Path | None = None,
    overlay_dir: Path | None = None,
    detection: Mapping[str, Any] | None = None,
    echo: Echo = quiet,
    session: Path | None = None,
    camera: str | None = None,
    kind: str = "markers",
) -> list[tuple[str, Blobs]]:
    """``kisscal detect``: blobs of image files, to one CSV and overlays optionally.

    The settings are ``detection`` (given values) on top of, with ``session`` and
    ``camera``, that camera's derived settings (``out/detection/<camera>.json``), or else
    settings derived from these images themselves (up to 24 of them, spread evenly).
    What was used is echoed. Returns ``(image path as given, blobs)`` per image. Every
    image is read and checked before anything is written, so a bad file leaves earlier
    outputs untouched.
    """
    given = dict(detection or {})
    images = [read_image(p) for p in paths]
    if session is not None:
        params = _session_params(Path(session), camera, kind, given, echo)
    else:
        picks = np.unique(np.linspace(0, len(images) - 1, min(len(images), 24)).astype(int))
        setup = configure_detection([images[i] for i in picks], given, kind=kind)  # type: ignore[arg-type]
        echo(f"detection settings from {len(picks)} of these images: {setup.summary()}")
        params = setup.params
    blobs = detect_sequence(images, params)
    tables = [(str(p), b) for p, b in zip(paths, blobs, strict=True)]
    for p, image, b in zip(paths, images, blobs, strict=True):
        why = hopeless(image, params) if len(b) == 0 else None
        if why is not None:
            echo(f"{p}: {why}")
    if out_csv is not None:
        write_blobs(out_csv, tables)
    if overlay_dir is not None:
        _write_overlays(Path(overlay_dir), paths, images, blobs)
    total = sum(len(b) for b in blobs)
    valid = sum(int(b.valid.sum()) for b in blobs)
    echo(f"{len(paths)} images: {total} blobs ({valid} valid)")
    return tables


def _session_params(
    root: Path, camera: str | None, kind: str, given: Mapping[str, Any], echo: Echo
) -> DetectionParams:
    """A session camera's derived settings with ``given`` on top."""
    if camera is None:
        raise InputError("--session needs --camera: whose derived settings to use")
    config = load_config(root)
    cam = select_cameras(config, camera)[0]
    params = stage_params(config, Overrides(detection=given))

    @writes_session
    def derive(root: Path) -> DetectionParams:
        return camera_detection(root, config, cam, kind, params, echo)

    detection = derive(root)
    echo(
        f"detection settings of camera {camera} ({kind} images of {root}): threshold "
        f"{detection.threshold:g}"
        + (" above the local background" if detection.background_tile_px else " (grey level)")
        + f", pixel aspect {detection.pixel_aspect:g}, oversize above "
        f"{detection.max_pixels} px"
    )
    return detection


def _write_overlays(
    folder: Path, paths: Sequence[Path], images: Sequence[np.ndarray], blobs: Sequence[Blobs]
) -> None:
    for k, (p, image, b) in enumerate(zip(paths, images, blobs, strict=True)):
        rgb = draw_overlay(image, b)
        _ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        # numbered and with the folder: frames of different cameras share file names
        name = f"{k:04d}_{Path(p).parent.name}_{Path(p).stem}_overlay.png"
        write_bytes(folder / name, buf.tobytes())
