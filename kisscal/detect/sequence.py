"""Blob detection of many images in parallel processes, decoding included.

The images of one or several sequences (a session's cameras) go to one pool of worker
processes in chunks of consecutive frames: every core stays busy until the last chunk
of the last sequence, and with a loader function each worker decodes its own frames, so
no image crosses a process boundary and memory does not grow with the number of frames.
The cameras' detection settings are derived the same way (:func:`surveyed`): each
camera's sample of frames surveyed in one worker, decoded there.
"""

from __future__ import annotations

import functools
import itertools
import os
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import Any, TypeVar

from numpy.typing import NDArray

from kisscal._shared import inherited, worker_pool
from kisscal.detect.blobs import Blobs
from kisscal.detect.configure import DetectionSetup, Kind, configure_detection
from kisscal.detect.params import DetectionParams
from kisscal.detect.pipeline import DEFAULT_PARAMS, STACK_PX, detect_frames
from kisscal.errors import InputError, KisscalError

T = TypeVar("T")
R = TypeVar("R")

#: Consecutive images a worker takes at a time (a video reader's sequential runs aside).
CHUNK_IMAGES = 32


@dataclass(frozen=True)
class ImageJob:
    """One sequence of images to detect: ``load(i)`` for ``i < count``, one setting."""

    load: Callable[[int], NDArray]
    count: int
    params: DetectionParams = DEFAULT_PARAMS
    chunksize: int = CHUNK_IMAGES


def _chunk(
    jobs: Sequence[ImageJob], chunk: tuple[int, int, int]
) -> tuple[list[Blobs], KisscalError | None]:
    """Blobs of images ``start:stop`` of job ``job`` (``chunk``), or the error that
    stopped them."""
    job, start, stop = chunk
    try:
        return _detected(jobs[job], start, stop), None
    except KisscalError as exc:  # a bad frame fails its own sequence, not the others
        return [], exc  # its kind kept: it is raised again in the caller's process


def _detected(spec: ImageJob, start: int, stop: int) -> list[Blobs]:
    """Blobs of images ``start:stop`` of ``spec``, detected a stack at a time
    (:func:`~kisscal.detect.pipeline.detect_frames`): at most :data:`STACK_PX` pixels
    of images held at once, however long the range (a video worker's share). Each image
    is loaded as the detection asks for it, so that it is thresholded straight after
    its decoding (its pixels still in the cache)."""
    images = (spec.load(i) for i in range(start, stop))
    out: list[Blobs] = []
    ahead: list[NDArray] = []  # the image that did not fit the last stack

    def stack() -> Iterator[NDArray]:
        pixels = 0
        for image in itertools.chain([ahead.pop()] if ahead else [], images):
            if pixels and pixels + image.size > STACK_PX:
                ahead.append(image)
                return
            pixels += image.size
            yield image

    while blobs := detect_frames(stack(), spec.params):
        out += blobs
    return out


def _inherited_item(index: int) -> Any:
    """``work(items[index])`` in a worker process of :func:`mapped`, of what it holds."""
    work, items = inherited()
    return work(items[index])


def mapped(work: Callable[[T], R], items: Sequence[T], workers: int | None = None) -> Iterator[R]:
    """``work(item)`` for every item, in one pool of ``workers`` processes (``None``: one
    per core; 1: in this process); the results in the order of ``items``.

    The workers hold ``work`` and ``items`` (inherited when forked, pickled once when
    spawned: :func:`kisscal._shared.worker_pool`, which also says when no process can be
    started, and the items are then done here); only the results travel.
    """
    n = min(workers or os.cpu_count() or 1, len(items))
    pool = worker_pool(n, (work, items)) if n > 1 else None
    if pool is None:
        yield from (work(item) for item in items)
        return
    with pool:
        yield from pool.map(_inherited_item, range(len(items)))


def _chunks(jobs: Sequence[ImageJob]) -> list[tuple[int, int, int]]:
    """``(job, start, stop)`` of every chunk, the jobs one after the other."""
    return [
        (j, start, min(start + job.chunksize, job.count))
        for j, job in enumerate(jobs)
        for start in range(0, job.count, job.chunksize)
    ]


def detect_jobs(
    jobs: Sequence[ImageJob], workers: int | None = None
) -> Iterator[tuple[int, list[Blobs] | KisscalError]]:
    """Detect every job's images in one pool of processes; yield each job when it is done.

    Parameters
    ----------
    jobs : sequence of ImageJob
        The sequences, each with its loader, length and detection settings.
    workers : int, optional
        Processes to use; ``None`` uses all cores, 1 runs in this process.

    Yields
    ------
    (int, list of Blobs or KisscalError)
        The job's index and its blobs (one table per image, in order), or the error a
        frame of it raised (the other jobs go on), in the order of ``jobs``.

    Notes
    -----
    Workers are forked and inherit the jobs (loaders and all): nothing is pickled but the
    results. Where processes are spawned (Windows) each worker gets the jobs pickled once;
    jobs that cannot be pickled, and a daemonic caller (a Dask worker), are detected in
    this process (:func:`kisscal._shared.worker_pool`). Chunks of every job share the
    pool, so a job's tail overlaps the next job.
    """
    if workers is None:
        workers = os.cpu_count() or 1
    if workers < 1:
        raise InputError(f"detect: workers must be >= 1, got {workers}")
    chunks = _chunks(jobs)
    yield from _by_job(jobs, chunks, mapped(functools.partial(_chunk, jobs), chunks, workers))


class JobsAhead:
    """Every job's images detected in the background, in one pool started at once
    (:func:`detect_ahead`): the caller goes on with other work meanwhile and takes each
    job's blobs when it needs them (:meth:`result`); :meth:`close` ends the pool."""

    def __init__(self, jobs: Sequence[ImageJob], pool: Executor) -> None:
        self._chunks, self._pool = _chunks(jobs), pool
        # every chunk queued now, the jobs in order: the workers take them as they come
        # free, so the first job's blobs are ready first
        self._futures = [pool.submit(_inherited_item, i) for i in range(len(self._chunks))]

    def result(self, job: int) -> list[Blobs] | KisscalError:
        """Job ``job``'s blobs (one table per image, in order) once detected, or the error
        a frame of it raised, as :func:`detect_jobs` yields them."""
        chunks = [i for i, (j, _start, _stop) in enumerate(self._chunks) if j == job]
        done: list[Blobs] = []
        for i in chunks:
            blobs, failed = self._futures[i].result()
            if failed is not None:
                return failed
            done += blobs
        return done

    def close(self, error: BaseException | None = None) -> None:
        """End the pool: the chunks not started are dropped, the running ones finish,
        and on an error (Ctrl-C above all) the workers are ended at once."""
        for future in self._futures:
            future.cancel()
        exc_type = type(error) if error is not None else None
        self._pool.__exit__(exc_type, error, None)  # kisscal._shared's pool: ends at once


def detect_ahead(jobs: Sequence[ImageJob], workers: int | None = None) -> JobsAhead | None:
    """Start detecting every job's images in ``workers`` background processes (``None``:
    one per core) and return at once; ``None`` where no background detection can run
    (one worker, no chunk to detect, or no process can be started:
    :func:`kisscal._shared.worker_pool`), the caller then detects when it needs the blobs.
    """
    chunks = _chunks(jobs)
    n = min(workers or os.cpu_count() or 1, len(chunks))
    pool = worker_pool(n, (functools.partial(_chunk, jobs), chunks)) if n > 1 else None
    return JobsAhead(jobs, pool) if pool is not None else None


def _by_job(
    jobs: Sequence[ImageJob],
    chunks: list[tuple[int, int, int]],
    results: Iterator[tuple[list[Blobs], KisscalError | None]],
) -> Iterator[tuple[int, list[Blobs] | KisscalError]]:
    """Gather the chunk results of each job, in order; a job ends at its last chunk."""
    done: list[Blobs] = []
    error: KisscalError | None = None
    for (job, _start, stop), (blobs, failed) in zip(chunks, results, strict=True):
        done += blobs
        error = error or failed
        if stop == jobs[job].count:
            yield job, (error if error is not None else done)
            done, error = [], None
    for j, job in enumerate(jobs):
        if job.count == 0:
            yield j, []


def detect_sequence(
    images: Sequence[NDArray] | Callable[[int], NDArray],
    params: DetectionParams = DEFAULT_PARAMS,
    *,
    count: int | None = None,
    workers: int | None = None,
    chunksize: int = CHUNK_IMAGES,
) -> list[Blobs]:
    """Detect blobs in many images, in parallel across processes.

    Parameters
    ----------
    images : sequence of ndarray, or callable ``index -> ndarray``
        The images, or a function that loads image ``index`` (e.g. the io layer's reader
        bound with :func:`functools.partial`): with a loader, decoding happens in the
        worker processes as well.
    params : DetectionParams
        Shared by all images.
    count : int, optional
        Number of images when ``images`` is a callable (required then).
    workers : int, optional
        Processes to use; ``None`` uses all cores, 1 runs in this process.
    chunksize : int
        Consecutive images handed to a worker at a time.

    Returns
    -------
    list of Blobs
        One table per image, in input order.

    Examples
    --------
    >>> import numpy as np
    >>> frames = [np.zeros((40, 60), np.uint8) for _ in range(3)]
    >>> frames[1][10:15, 20:25] = 200
    >>> [len(b) for b in detect_sequence(frames, workers=1)]
    [0, 1, 0]
    """
    if callable(images):
        if count is None:
            raise InputError("detect: count is required when images is a loader function")
        load, n = images, count
    else:
        load, n = images.__getitem__, len(images)
    if chunksize < 1:
        raise InputError(f"detect: chunksize must be >= 1, got {chunksize}")
    ((_, blobs),) = detect_jobs([ImageJob(load, n, params, chunksize)], workers)
    if isinstance(blobs, KisscalError):
        raise blobs
    return blobs


@dataclass(frozen=True)
class SurveyJob:
    """One camera's sample of frames to derive its settings from: ``load(i)`` for
    ``i < count``, with what the user gave and what is known
    (:func:`~kisscal.detect.configure.configure_detection`'s arguments)."""

    load: Callable[[int], NDArray]
    count: int
    given: Mapping[str, Any] = field(default_factory=dict)
    kind: Kind = "markers"
    pixel_aspect: float | None = None
    aspect_why: str = "known for this camera"

    def derive(self) -> DetectionSetup:
        """The camera's settings, from its frames decoded here."""
        return configure_detection(
            [self.load(i) for i in range(self.count)],
            self.given,
            kind=self.kind,
            pixel_aspect=self.pixel_aspect,
            aspect_why=self.aspect_why,
        )


def surveyed(job: SurveyJob) -> DetectionSetup | KisscalError:
    """``job``'s settings, or the error that stopped them (raised again by the caller, the
    other cameras' settings done): what each worker of :func:`mapped` does for a camera.

    References
    ----------
    Shafiq, M. S., Tümer, S. T., & Güler, H. C. (2001). Marker detection and trajectory
    generation algorithms for a multicamera based gait analysis system. Mechatronics,
    11(4) (whose settings were tuned to each camera by hand).
    """
    try:
        return job.derive()
    except KisscalError as exc:
        return exc
