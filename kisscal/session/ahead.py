"""Trials' blobs detected ahead, in background processes, while the session goes on.

``kisscal run`` knows every trial it will process from the start, and a trial's blobs
depend only on its images and its cameras' marker settings (derived once for the
session). Most of what follows detection runs in one process (the calibration's DLT,
each trial's reconstruction and tracking), so inside :func:`detecting_ahead` the run
starts detecting every trial's images at once in a pool of its own (:meth:`Ahead.start`,
:func:`kisscal.detect.sequence.detect_ahead`) and goes on: the other core detects the
next trials while this one calibrates and tracks. A trial's detection
(:func:`kisscal.session.runner.camera_blobs`) takes its cameras' blobs from there
(:meth:`Ahead.take`), the same blobs it would have detected, and caches them as before.
The run owns its :class:`Ahead` and hands it down (no module state).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np

from kisscal.detect import Blobs, DetectionParams, ImageJob
from kisscal.detect.sequence import JobsAhead, detect_ahead
from kisscal.errors import KisscalError
from kisscal.io.frames import source_files
from kisscal.io.store import SessionStore
from kisscal.session.trials import SizedFrames


class Ahead:
    """The trials' blobs of one ``kisscal run`` detected in the background: the run owns
    it (:func:`detecting_ahead`) and hands it down to where a trial's blobs are taken
    (:func:`kisscal.session.runner.camera_blobs`, through the stage's call), so no
    module holds it.

    It holds the pool of :func:`~kisscal.detect.sequence.detect_ahead` and each job's
    index in it by (blob cache, key), for the process that made it (``_pid``: a forked
    worker inherits the object, not the pool, and detects its own blobs).
    """

    def __init__(self) -> None:
        self._pid = os.getpid()
        self._jobs: JobsAhead | None = None
        self._slots: dict[tuple[Path, str], int] = {}

    @property
    def started(self) -> bool:
        """Whether its background detection was started (once a run)."""
        return self._jobs is not None

    def start(self, jobs: Mapping[tuple[Path, str], ImageJob], workers: int | None = None) -> bool:
        """Detect ``jobs`` in ``workers`` background processes (``None``: one per core),
        each job under its blob cache and key (what :meth:`take` is asked for). Once:
        False when started already, in another process than the run's, or where nothing
        can run in the background (:func:`~kisscal.detect.sequence.detect_ahead`)."""
        if self.started or not jobs or os.getpid() != self._pid:
            return False
        found = detect_ahead(list(jobs.values()), workers)
        if found is None:
            return False
        self._jobs, self._slots = found, {slot: j for j, slot in enumerate(jobs)}
        return True

    def take(self, cache: Path, key: str) -> list[Blobs] | KisscalError | None:
        """The blobs detected ahead for ``cache`` under ``key`` (waiting for them), or the
        error a frame raised; None when they were not detected ahead (nor with this key)."""
        if os.getpid() != self._pid or self._jobs is None:
            return None
        job = self._slots.pop((cache, key), None)
        return None if job is None else self._jobs.result(job)

    def close(self, error: BaseException | None = None) -> None:
        """End the background pool (at once after an error)."""
        jobs, self._jobs, self._slots = self._jobs, None, {}
        if jobs is not None and os.getpid() == self._pid:
            jobs.close(error)


@contextlib.contextmanager
def detecting_ahead() -> Iterator[Ahead]:
    """A run's :class:`Ahead`, whose pool ends with the block (at once when it raised)."""
    ahead = Ahead()
    try:
        yield ahead
    except BaseException as exc:
        ahead.close(exc)
        raise
    ahead.close(None)


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
