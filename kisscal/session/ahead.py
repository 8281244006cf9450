"""Trials' blobs detected ahead, in background processes, while the session goes on.

``kisscal run`` knows every trial it will process from the start, and a trial's blobs
depend only on its images and its cameras' marker settings (derived once for the
session). Most of what follows detection runs in one process (the calibration's DLT,
each trial's reconstruction and tracking), so inside :func:`detecting_ahead` the run
starts detecting every trial's images at once in a pool of its own (:func:`start`,
:func:`kisscal.detect.sequence.detect_ahead`) and goes on: the other core detects the
next trials while this one calibrates and tracks. A trial's detection
(:func:`kisscal.session.runner.camera_blobs`) takes its cameras' blobs from there
(:func:`take`), the same blobs it would have detected, and caches them as before.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.detect import Blobs, DetectionParams, ImageJob
from kisscal.detect.sequence import detect_ahead
from kisscal.errors import KisscalError
from kisscal.io.frames import source_files
from kisscal.io.store import SessionStore
from kisscal.session.trials import SizedFrames

#: The background detection of this process (``pid``): by (blob cache, key), each
#: job's index in it.
_STATE: dict[str, Any] = {"ahead": None, "pid": None, "slots": {}}


@contextlib.contextmanager
def detecting_ahead() -> Iterator[None]:
    """A block where :func:`start` may detect in the background; its pool ends with the
    block (at once when the block raised). Nested blocks share the outer one's."""
    if _STATE["pid"] == os.getpid():
        yield
        return
    _STATE.update(ahead=None, pid=os.getpid(), slots={})
    try:
        yield
    except BaseException as exc:
        _stop(exc)
        raise
    _stop(None)


def _stop(error: BaseException | None) -> None:
    ahead = _STATE["ahead"]
    _STATE.update(ahead=None, pid=None, slots={})
    if ahead is not None:
        ahead.close(error)


def started() -> bool:
    """Whether this block has started its background detection (or has none to start:
    outside :func:`detecting_ahead`, in a worker process)."""
    return _STATE["pid"] != os.getpid() or _STATE["ahead"] is not None


def start(jobs: Mapping[tuple[Path, str], ImageJob], workers: int | None = None) -> bool:
    """Detect ``jobs`` in ``workers`` background processes (``None``: one per core), each
    job under its blob cache and key (what :func:`take` is asked for). Once a block:
    False when one was started already, outside the block, or where nothing can run in
    the background (:func:`~kisscal.detect.sequence.detect_ahead`)."""
    if started() or not jobs:
        return False
    ahead = detect_ahead(list(jobs.values()), workers)
    if ahead is None:
        return False
    _STATE.update(ahead=ahead, slots={slot: j for j, slot in enumerate(jobs)})
    return True


def take(cache: Path, key: str) -> list[Blobs] | KisscalError | None:
    """The blobs detected ahead for ``cache`` under ``key`` (waiting for them), or the
    error a frame raised; None when they were not detected ahead (nor with this key)."""
    if _STATE["pid"] != os.getpid():
        return None
    job = _STATE["slots"].pop((cache, key), None)
    return None if job is None else _STATE["ahead"].result(job)


def chunk_size(frames: Sequence, workers: int | None) -> int:
    """Consecutive frames a detection worker takes at a time: 32, or for a video (decoded
    in order) an even share of the whole, so that each worker seeks once."""
    n_workers = max(workers or os.cpu_count() or 1, 1)
    if not getattr(frames, "sequential", False):
        return 32
    share = -(-len(frames) // n_workers)
    return max(share + share % 2, 2)  # even: both fields of a frame go to one worker


def blob_slot(
    store: SessionStore,
    stem: str,
    camera: str,
    frames: Sequence[np.ndarray],
    fields: str | None,
    detection: DetectionParams,
) -> tuple[Path, str]:
    """A camera's blob cache for ``frames`` (``out/cache/blobs/<stem>-<camera>.npz``) and
    the key its blobs are kept under: its source files, fields and detection settings."""
    key = store.key("detect", source_files(frames), fields, detection)
    return store.blobs_cache(stem, camera), key


def image_job(
    frames: Sequence[np.ndarray],
    camera: str,
    size_px: tuple[int, int] | None,
    detection: DetectionParams,
    workers: int | None,
) -> ImageJob:
    """The detection of a camera's ``frames``, each checked for its size when read."""
    sized = SizedFrames(frames, camera, size_px)
    return ImageJob(sized.__getitem__, len(sized), detection, chunk_size(sized, workers))
