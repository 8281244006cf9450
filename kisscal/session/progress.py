"""Where the pipeline reports how far a stage has got, and its one-line messages.

The CLI installs a progress bar with :func:`reporting_progress`; library calls and tests
stay silent. Like logging, the progress sink is set for the running context rather than
passed through every stage call.
"""

from __future__ import annotations

import contextlib
import contextvars
from collections.abc import Callable, Iterable, Iterator
from typing import TypeVar

T = TypeVar("T")

#: Where a session function prints its one-line messages (``typer.echo``, ``print`` ...).
Echo = Callable[[str], object]


def quiet(_: str) -> None:
    """An :data:`Echo` that prints nothing (the default of library calls)."""
    return None


class Progress:
    """Progress of the pipeline's stages; the base class ignores it."""

    def start(self, stage: str, total: int) -> None:
        """A stage of ``total`` steps begins."""

    def advance(self, steps: int = 1) -> None:
        """Steps of the current stage are done."""


_PROGRESS: contextvars.ContextVar[Progress | None] = contextvars.ContextVar(
    "kisscal_progress", default=None
)


def steps(items: Iterable[T], stage: str) -> Iterator[T]:
    """Iterate over ``items``, reporting each one done (after its loop body) as a step."""
    items = list(items)
    return counted(items, stage, len(items))


def counted(items: Iterable[T], stage: str, total: int) -> Iterator[T]:
    """Like :func:`steps` for ``total`` items that arrive one at a time (a generator)."""
    progress = _PROGRESS.get() or Progress()
    progress.start(stage, total)
    for item in items:
        yield item
        progress.advance()


@contextlib.contextmanager
def reporting_progress(progress: Progress) -> Iterator[None]:
    """Report the progress of pipeline stages run inside the block to ``progress``."""
    token = _PROGRESS.set(progress)
    try:
        yield
    finally:
        _PROGRESS.reset(token)
