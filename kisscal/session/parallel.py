"""A stage's work for each camera in parallel processes (detection surveys, grid fits).

A camera's detection survey and grid fit read only that camera's images and write only
that camera's files (``out/detection/<camera>.json``, ``out/linearisation/<camera>.json``,
its figure), so cameras can be done side by side. Workers are forked: the work function
and its inputs are inherited, not pickled; results come back pickled, and every message a
worker says is repeated by the parent, camera by camera, in the cameras' order.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any, TypeVar

import cv2

from kisscal.errors import KisscalError
from kisscal.session.progress import Echo, counted

T = TypeVar("T")
R = TypeVar("R")

_WORK: dict[str, Any] = {}


def _init(work: Callable[[Any, Echo], Any], items: Sequence[Any]) -> None:
    cv2.setNumThreads(0)  # see kisscal.detect.sequence: forked children and OpenCV's pool
    _WORK["work"], _WORK["items"] = work, items


def _call(work: Callable[[Any, Echo], Any], item: Any) -> tuple[Any, list[str]]:
    """``work(item)``'s result (or the KisscalError it raised) and what it said."""
    said: list[str] = []
    try:
        return work(item, said.append), said
    except KisscalError as exc:
        return exc, said


def _one(index: int) -> tuple[Any, list[str]]:
    return _call(_WORK["work"], _WORK["items"][index])


def _results(
    work: Callable[[Any, Echo], Any], items: Sequence[Any], workers: int
) -> Iterator[tuple[Any, list[str]]]:
    if workers <= 1:
        yield from (_call(work, item) for item in items)
        return
    with ProcessPoolExecutor(
        max_workers=workers,
        mp_context=multiprocessing.get_context("fork"),
        initializer=_init,
        initargs=(work, items),
    ) as pool:
        yield from pool.map(_one, range(len(items)))


def each_camera(
    work: Callable[[T, Echo], R],
    items: Sequence[T],
    stage: str,
    echo: Echo,
    workers: int | None = None,
) -> list[R]:
    """``work(item, echo)`` for every item, in parallel processes; the results in order.

    ``workers`` None uses every core, 1 works in this process. The first
    :class:`KisscalError` an item raised is raised again once every item is done (the
    others' files are written).
    """
    n = min(workers or os.cpu_count() or 1, len(items))
    if "fork" not in multiprocessing.get_all_start_methods():
        n = 1
    results: list[R] = []
    failed: KisscalError | None = None
    for result, said in counted(_results(work, items, n), stage, len(items)):
        for line in said:
            echo(line)
        if isinstance(result, KisscalError):
            failed = failed or result
        results.append(result)
    if failed is not None:
        raise failed
    return results
