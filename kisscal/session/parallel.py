"""A stage's work for each camera in parallel processes (grid fits).

A camera's grid fit (with the survey of its grid frames) reads only that camera's
images and writes only that camera's files (``out/detection/<camera>.json``,
``out/linearisation/<camera>.json``, its figure), so cameras can be done side by side,
in the detector's pool (:func:`kisscal.detect.sequence.mapped`). Workers are forked: the
work function and its inputs are inherited, not pickled (spawned workers, on Windows,
get them pickled once: the work function must then be a module-level function or a
``functools.partial`` of one, else the cameras are done in this process); results come
back pickled, and every message a worker says is repeated by the parent, camera by
camera, in the cameras' order, and every figure it drew is handed back to the parent's
figure process
(:func:`kisscal.session.figures.handing_back`).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from kisscal.detect.sequence import mapped
from kisscal.errors import KisscalError
from kisscal.session.figures import handing_back, submit_packed
from kisscal.session.progress import Echo, counted

T = TypeVar("T")
R = TypeVar("R")


#: What a worker returns for one item: the result (or the KisscalError it raised), what it
#: said, and the figures it drew (pickled, for the parent's figure process).
_Done = tuple[Any, list[str], list[bytes]]


def _call(work: Callable[[Any, Echo], Any], item: Any) -> _Done:
    """``work(item)``'s result (or the KisscalError it raised), what it said and the
    figures it drew."""
    said: list[str] = []
    with handing_back() as figures:
        try:
            result = work(item, said.append)
        except KisscalError as exc:
            result = exc
    return result, said, figures


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
    results: list[R] = []
    failed: KisscalError | None = None
    done = mapped(functools.partial(_call, work), items, n)
    for result, said, figures in counted(done, stage, len(items)):
        for line in said:
            echo(line)
        for packed in figures:
            submit_packed(packed)
        if isinstance(result, KisscalError):
            failed = failed or result
        results.append(result)
    if failed is not None:
        raise failed
    return results
