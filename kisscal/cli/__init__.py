"""The ``kisscal`` command line: a thin typer layer over :mod:`kisscal.session`.

Every user error is reported on one line, ``kisscal <command>: error: ...``, with exit
code 2; ``kisscal check`` exits 1 when a quality limit is exceeded; Ctrl-C prints one
``interrupted`` line and exits 130. The log goes to stderr, data to stdout
(:mod:`kisscal.cli.log`).
"""

from __future__ import annotations

import _thread
import multiprocessing
import sys
import threading
from typing import Any

import typer

from kisscal.cli import blas  # noqa: F401  (first of kisscal: sets the BLAS threads before NumPy)
from kisscal.cli import commands as _commands  # noqa: F401  (registers the commands)
from kisscal.cli.app import app
from kisscal.cli.log import configure, level_from_flags
from kisscal.errors import KisscalError

__all__ = ["app", "main"]


def _click_class(name: str) -> type[Exception]:
    """A class of the click library typer is built on, found without a private import."""
    return next(c for c in typer.BadParameter.__mro__ if c.__name__ == name)


UsageError = _click_class("UsageError")
ClickException = _click_class("ClickException")


#: Exit code of a command stopped by Ctrl-C (128 + SIGINT, as shells report it).
INTERRUPTED = 130


def _command_name(args: list[str]) -> str:
    """``kisscal <command>`` for messages: the first argument naming a command."""
    names = {c.name or c.callback.__name__ for c in app.registered_commands if c.callback}
    first = next((a for a in args if a in names), None)
    return f"kisscal {first}" if first else "kisscal"


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the typer app, turning every user error into one line.

    Usage errors (a missing argument, a bad number) and :class:`KisscalError` from any
    stage are printed as ``kisscal <command>: error: ...`` with exit code 2, never as a
    traceback.
    """
    level, args = level_from_flags(sys.argv[1:] if argv is None else list(argv))
    configure(level)
    sys.unraisablehook = _keep_interrupts
    where = _command_name(args)
    try:
        rv = app(args=args or ["--help"], prog_name="kisscal", standalone_mode=False)
    except KisscalError as exc:
        _fail(where, str(exc), exc.exit_code)
    except OSError as exc:  # a path the user gave cannot be read or written
        detail = f": {exc.filename}" if exc.filename else ""
        _fail(where, f"{exc.strerror or exc}{detail}", 2)
    except ClickException as exc:
        _fail(where, exc.format_message(), 2 if isinstance(exc, UsageError) else exc.exit_code)
    except (typer.Abort, KeyboardInterrupt):  # Ctrl-C: worker processes ignore it
        rv = INTERRUPTED
    if rv == INTERRUPTED:  # typer turns a KeyboardInterrupt into this exit code
        _end_workers()
        _fail(where, "interrupted", INTERRUPTED)
    sys.exit(rv if isinstance(rv, int) else 0)


#: How long after a lost Ctrl-C :func:`_keep_interrupts` raises it again (s): time for
#: the hook to return.
_REPEAT_INTERRUPT_S = 0.01


def _keep_interrupts(unraisable: Any) -> None:
    """Do not lose a Ctrl-C that Python could not raise where it arrived.

    A SIGINT that arrives while the process forks a worker is raised in a callback run
    just after the fork (logging's lock release) or in a finaliser, where it is only
    printed and dropped. It is raised again in the main thread instead, so the command
    stops with its one ``interrupted`` line: from another thread, a moment later, as
    raised here it would land in this hook and be dropped again (a whole-suite run saw
    the traceback of this very line, and the run went on until a second Ctrl-C).
    """
    if issubclass(unraisable.exc_type, KeyboardInterrupt):
        later = threading.Timer(_REPEAT_INTERRUPT_S, _thread.interrupt_main)
        later.daemon = True  # a command ending meanwhile does not wait for it
        later.start()
        return
    sys.__unraisablehook__(unraisable)


def _end_workers() -> None:
    """Terminate every worker process still running when Ctrl-C stops a command.

    The interrupted stage's pool normally ends its workers as the error leaves it. One
    that is still referenced (a generator or a frame kept by the error's traceback) is
    shut down only at exit, and the standard pool then finishes every task still queued
    (the workers ignore Ctrl-C) before Python may exit: a whole-suite run saw ``kisscal
    run`` print its ``interrupted`` line and wait over 120 s.
    """
    for child in multiprocessing.active_children():
        child.terminate()


def _fail(where: str, message: str, code: int) -> None:
    message = " ".join(message.split())  # one line, whatever the exception held
    typer.echo(f"{where}: error: {message}", err=True)
    sys.exit(code)
