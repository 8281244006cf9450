"""Stage figures drawn beside the pipeline, in a background process.

A stage figure (a camera's grid correction, a trial's epipolar lines, its tracks) takes
matplotlib a second or more, and the numbers it illustrates are written already. Inside
:func:`drawing_beside` (the outermost session command holds it), figures go to one
background process that draws them while the stage goes on: reconstruction and tracking
use one core, so the other one draws. The block ends only when every figure is written,
so a command's outputs are complete when it returns. The block owns that process and its
figures (a :class:`Figures`), which the stages inside it find in their context. A worker
process of the stage (:func:`kisscal.session.runner.each_camera`) hands its figures back
with its result (:func:`handing_back`), and the session's process passes them on to the
background one: matplotlib is then imported and its figures drawn in one process, not in
every worker. Anywhere else (a plain library call) a figure is drawn at once.

A figure is drawn only when its PNG is not there already for the same drawing function,
data and code (:func:`figure_key`): a session run again redraws only the figures whose
content changed.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import functools
import io
import os
import pickle
import warnings
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import worker_pool
from kisscal.io.store import SessionStore

T = TypeVar("T")


@dataclasses.dataclass
class Figures:
    """Where a block's figures go: a session command's background process (``pool``,
    started by ``pid``: a forked child inherits the object, not the process) and the
    figures submitted to it (``pending``), or, inside :func:`handing_back`, a list
    (``handed``) a worker process returns with its result.

    The outermost session command owns it (:func:`drawing_beside`), and the stages
    find it in their context (:data:`_FIGURES`), as they find the progress sink
    (:mod:`kisscal.session.progress`): a figure is drawn deep inside a stage, and no
    stage's signature carries it.
    """

    pool: ProcessPoolExecutor | None = None
    pid: int | None = None
    pending: list[Future] = dataclasses.field(default_factory=list)
    handed: list[bytes] | None = None

    @property
    def here(self) -> ProcessPoolExecutor | None:
        """The background process, when this process started it."""
        return self.pool if self.pid == os.getpid() else None


#: The figures of the running session command (None: a plain library call, figures are
#: drawn at once).
_FIGURES: contextvars.ContextVar[Figures | None] = contextvars.ContextVar(
    "kisscal_figures", default=None
)


def draw_figure(path: Path, draw: Callable[..., Any], args: tuple) -> bool:
    """Draw ``draw(*args)`` into ``path``; a figure that cannot be drawn (a degenerate
    trial) is skipped: figures illustrate numbers that are already written. True when
    the figure was written."""
    # matplotlib and the report's pages (some 1.3 s of import on a loaded two-core
    # machine) only when a figure is drawn: in the figure process, never in the session's
    import matplotlib

    from kisscal.report.html import FIGURE_RC, save_figure

    try:
        with warnings.catch_warnings(), matplotlib.rc_context(FIGURE_RC):
            warnings.simplefilter("ignore")
            save_figure(draw(*args), path)
    except (ValueError, IndexError):
        return False
    return True


def submit_figure(path: Path, draw: Callable[..., Any], args: tuple) -> None:
    """Draw a figure in the background process when there is one here, hand it back
    inside :func:`handing_back`, else draw it now; not at all when ``path`` holds it
    already (:func:`figure_key`).

    ``draw`` is a module-level function (pickled by name for the background process)."""
    try:
        # its key, and the figure pickled with it to travel to the drawing process; data
        # that cannot be pickled is drawn at once instead
        key = figure_key(path, draw, args)
        packed = pickle.dumps((path, draw, args, key), protocol=pickle.HIGHEST_PROTOCOL)
    except (pickle.PicklingError, TypeError, AttributeError, ValueError, RecursionError):
        draw_figure(path, draw, args)
        return
    if SessionStore.is_current(path, key):
        return
    figures = _FIGURES.get()
    if figures is not None and figures.handed is not None:
        figures.handed.append(packed)
    else:
        submit_packed(packed)


def submit_packed(packed: bytes) -> None:
    """A figure handed back by :func:`handing_back`: to the background process when
    there is one here, else drawn now."""
    figures = _FIGURES.get()
    pool = None if figures is None else figures.here
    if pool is None:
        _draw_packed(packed)
        return
    figures.pending.append(pool.submit(_draw_packed, packed))


@functools.cache
def _drawing_code() -> NDArray[np.uint8]:
    """kisscal's source files and matplotlib's version, as bytes: the code a figure is
    drawn with."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        parts = [version("matplotlib").encode()]
    except PackageNotFoundError:  # the figures then fail on import, as before
        parts = []
    package = Path(__file__).resolve().parents[1]
    for source in sorted(package.rglob("*.py")):
        parts += [source.relative_to(package).as_posix().encode(), source.read_bytes()]
    return np.frombuffer(b"\0".join(parts), dtype=np.uint8)


def figure_key(path: Path, draw: Callable[..., Any], args: tuple) -> str:
    """The key (:meth:`kisscal.io.store.SessionStore.key`) of the figure ``path`` drawn
    by ``draw(*args)``: the function and its data, pickled without shared references
    (two equal arguments give the same bytes however they were built), and the code that
    draws them (:func:`_drawing_code`). The same key, the same PNG."""
    buf = io.BytesIO()
    pickler = pickle.Pickler(buf, protocol=pickle.HIGHEST_PROTOCOL)
    pickler.fast = True  # no memo: each object written out where it occurs
    pickler.dump((draw, args))
    data = np.frombuffer(buf.getvalue(), dtype=np.uint8)
    return SessionStore(path.parent).key("stage figure", _drawing_code(), data)


def _draw_packed(packed: bytes) -> None:
    path, draw, args, key = pickle.loads(packed)
    if SessionStore.is_current(path, key):
        return
    SessionStore.forget(path)  # a figure that is not redrawn keeps no key
    if draw_figure(path, draw, args):
        SessionStore.mark_current(path, key)


@contextlib.contextmanager
def handing_back() -> Iterator[list[bytes]]:
    """Collect the block's figures (pickled) instead of drawing them: a worker process
    returns them with its result, and the session's process gives each to
    :func:`submit_packed`."""
    figures = _FIGURES.get()
    token = None
    if figures is None:  # outside any session command: this block's own
        figures = Figures()
        token = _FIGURES.set(figures)
    outer = figures.handed
    figures.handed = handed = []
    try:
        yield handed
    finally:
        figures.handed = outer
        if token is not None:
            _FIGURES.reset(token)


def after_figures(work: Callable[..., T], *args: Any) -> T:
    """``work(*args)`` in the background process once the figures submitted so far are
    drawn (its tasks run in order), or here when there is none: the report, whose own
    figures then need no second import of matplotlib. ``work`` is a module-level
    function; its error is raised here."""
    figures = _FIGURES.get()
    pool = None if figures is None else figures.here
    if pool is None:
        return work(*args)
    return pool.submit(work, *args).result()


def wait_for_figures() -> None:
    """Wait until every figure submitted so far is written (before a report reads them)."""
    figures = _FIGURES.get()
    if figures is None or figures.pid != os.getpid():
        return
    pending, figures.pending = figures.pending, []
    for future in pending:
        error = future.exception()
        if error is not None:
            raise error


@contextlib.contextmanager
def drawing_beside() -> Iterator[None]:
    """Draw the block's figures in a background process; wait for them at its end.

    Nested blocks share the outer block's process. A figure that failed (a bug, not a
    degenerate trial) raises its error when the block ends.
    """
    outer = _FIGURES.get()
    if outer is not None and outer.pid == os.getpid():
        yield
        return
    pool = worker_pool(1) if (os.cpu_count() or 1) >= 2 else None  # a core to spare
    # figures handed back stay handed back (a worker's command inside handing_back)
    figures = Figures(pool, os.getpid(), [], None if outer is None else outer.handed)
    token = _FIGURES.set(figures)
    try:
        yield
    except BaseException:
        _stop(figures, cancel=True)  # the block's own error is the one to report
        raise
    finally:
        _FIGURES.reset(token)
    _stop(figures, cancel=False)


def _stop(figures: Figures, cancel: bool) -> None:
    """End the background process: after its figures are drawn, or at once."""
    pool, pending = figures.pool, figures.pending
    figures.pool, figures.pid, figures.pending = None, None, []
    if pool is None:
        return
    try:
        errors = [] if cancel else [f.exception() for f in pending]
    finally:
        pool.shutdown(wait=True, cancel_futures=cancel)
    for error in errors:
        if error is not None:
            raise error
