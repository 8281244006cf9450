"""The command line's log: every message goes to stderr through stdlib :mod:`logging`.

Standard output carries data only (``kisscal detect``'s blob table, ``--version``, help),
so it can be piped or redirected; the log is on stderr whether or not stderr is a
terminal. ``--quiet`` keeps warnings and errors, ``--verbose`` adds debug lines (stage
timings) and prefixes every line with the seconds since the command started.

The pipeline's stages say their one-line messages through an ``echo`` callable
(:data:`kisscal.session.progress.Echo`); :func:`say` is the one the CLI gives them. It
logs a line at the level its first word names: ``warning`` -> WARNING, ``problem`` /
``failed`` / ``FAILED`` -> ERROR, anything else INFO.
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Callable

#: The logger of every kisscal message (stages may log to its children ``kisscal.*``).
LOG = logging.getLogger("kisscal")

#: Command-line flags that set the log level, wherever they stand on the command line.
QUIET_FLAGS = ("--quiet", "-q")
VERBOSE_FLAGS = ("--verbose", "-v")

_ERROR_WORDS = ("problem", "failed", "error")


class _Stderr(logging.Handler):
    """Writes each record to the current ``sys.stderr`` (tests swap it), or to ``sink``
    while progress bars are drawn there (the line goes above the bars)."""

    def __init__(self) -> None:
        super().__init__()
        self.sink: Callable[[str], object] | None = None

    def emit(self, record: logging.LogRecord) -> None:
        try:
            line = self.format(record)
            if self.sink is not None:
                self.sink(line)
            else:
                sys.stderr.write(line + "\n")
                sys.stderr.flush()
        except Exception:  # pragma: no cover - logging must never stop the pipeline
            self.handleError(record)


_HANDLER = _Stderr()


def configure(level: int) -> None:
    """Send the ``kisscal`` log to stderr at ``level`` (once per process; later calls only
    change the level)."""
    if _HANDLER not in LOG.handlers:
        LOG.addHandler(_HANDLER)
        LOG.propagate = False  # a host application's root handlers would print it twice
    verbose = level <= logging.DEBUG
    fmt = "[%(relativeCreated)8.0f ms] %(message)s" if verbose else "%(message)s"
    _HANDLER.setFormatter(logging.Formatter(fmt))
    LOG.setLevel(level)


def level_from_flags(args: list[str]) -> tuple[int, list[str]]:
    """The log level the flags in ``args`` ask for, and ``args`` without them.

    The flags are taken anywhere before a ``--`` (``kisscal run S --quiet`` as well as
    ``kisscal --quiet run S``); the last one given wins.
    """
    end = args.index("--") if "--" in args else len(args)
    level, rest = logging.INFO, []
    for i, arg in enumerate(args):
        if i < end and arg in QUIET_FLAGS:
            level = logging.WARNING
        elif i < end and arg in VERBOSE_FLAGS:
            level = logging.DEBUG
        else:
            rest.append(arg)
    return level, rest


def level_of(line: str) -> int:
    """The level of a stage's message, from its first word."""
    words = line.split(maxsplit=1)
    first = words[0].rstrip(":").lower() if words else ""
    if first == "warning":
        return logging.WARNING
    if first in _ERROR_WORDS:
        return logging.ERROR
    return logging.INFO


_COUNTS = {"warnings": 0}


def say(line: str) -> None:
    """The ``echo`` of every command: log ``line`` at the level it names."""
    level = level_of(line)
    _COUNTS["warnings"] += level == logging.WARNING
    LOG.log(level, line)


def warnings_logged() -> int:
    """How many warnings :func:`say` has logged in this process."""
    return _COUNTS["warnings"]


def set_sink(sink: Callable[[str], object] | None) -> None:
    """Write log lines through ``sink`` (progress bars' console), or stderr with None."""
    _HANDLER.sink = sink
