"""The typer application, its shared arguments and the progress display of every command."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Iterator
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as package_version
from pathlib import Path
from types import ModuleType
from typing import Annotated

import typer

import kisscal.cli.log as log
from kisscal._text import plural

app = typer.Typer(
    name="kisscal",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100},
)


def _session_folder(path: Path) -> Path:
    """The session folder a command is given: the folder, or its ``session.toml``; the
    current folder by name when none is given (messages then say which it was)."""
    if path.name == "session.toml" and not path.is_dir():
        path = path.parent
    return Path.cwd() if path == Path() else path


SessionArg = Annotated[
    Path,
    typer.Argument(
        help="Session folder (holds session.toml), or its session.toml.",
        metavar="SESSION",
        callback=_session_folder,
    ),
]
SessionHereArg = Annotated[
    Path,
    typer.Argument(
        help="Session folder (holds session.toml), or its session.toml [default: this folder].",
        metavar="[SESSION]",
        callback=_session_folder,
        show_default=False,
    ),
]
TrialArg = Annotated[str, typer.Argument(help="Trial name from session.toml.", metavar="TRIAL")]


def example_epilog(*lines: str) -> str:
    """A help epilog with example command lines (click keeps ``\\b`` paragraphs as written)."""
    return "\b\nExamples:\n" + "\n".join(f"  {line}" for line in lines)


def _version(value: bool) -> None:
    if value:
        try:
            typer.echo(f"kisscal {package_version('kisscal')}")
        except PackageNotFoundError:  # pragma: no cover - run from a source tree
            typer.echo("kisscal (not installed)")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version."),
    ] = False,
    quiet: Annotated[  # read by kisscal.cli.main wherever it stands; declared for --help
        bool, typer.Option("--quiet", "-q", help="Log warnings and errors only.")
    ] = False,
    verbose: Annotated[
        bool, typer.Option("--verbose", "-v", help="Also log debug lines, timed.")
    ] = False,
) -> None:
    """Calibration and reconstruction for marker-based multi-camera gait capture.

    A session folder holds session.toml and the camera images; every output goes to its
    out/ folder. Start with `kisscal demo`, then `kisscal run SESSION` on your own.
    The log goes to stderr (--quiet and --verbose may stand anywhere on the line), data
    to stdout.
    """


def run_verdict(summary: dict, seconds: float, report: Path) -> str:
    """The last line of ``kisscal run``: what was made, how long it took, what to read."""
    trials = summary.get("trials", {})
    tracks = sum(int(t.get("trajectories", 0) or 0) for t in trials.values())
    warned = log.warnings_logged()
    notes = f"; {plural(warned, 'warning')} above" if warned else ", no warnings"
    return (
        f"kisscal run: done in {seconds:.0f} s: {plural(len(trials), 'trial')} processed, "
        f"{plural(tracks, 'trajectory')}{notes}; report: {report}"
    )


def session_package() -> ModuleType:
    """:mod:`kisscal.session`, the functions every command is a thin layer over, imported
    when a command runs rather than when the CLI starts: it brings NumPy, OpenCV and
    SciPy (linalg, optimize, ndimage, sparse, spatial, interpolate), some 3 s of import on
    a loaded two-core machine, which ``kisscal --help`` (0.05 s of kisscal imports) and a
    mistyped option never need."""
    from kisscal import session

    return session


@contextlib.contextmanager
def progress_bars() -> Iterator[Callable[[str], object]]:
    """A progress bar per pipeline stage on a terminal (stderr); none when it is redirected.

    Yields the function that logs the pipeline's messages (:func:`kisscal.cli.log.say`),
    written above the bars while they are drawn.
    """
    from rich.console import Console
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    session = session_package()
    console = Console(stderr=True)
    if not console.is_terminal or log.LOG.getEffectiveLevel() > logging.INFO:
        yield log.say
        return

    class Bars(session.Progress):
        def __init__(self, bars: Progress) -> None:
            self.bars = bars
            self.task: int | None = None

        def start(self, stage: str, total: int) -> None:
            self.task = self.bars.add_task(stage, total=max(total, 1))

        def advance(self, steps: int = 1) -> None:
            if self.task is not None:
                self.bars.advance(self.task, steps)

    columns = (
        TextColumn("{task.description:<34}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=console) as bars, session.reporting_progress(Bars(bars)):
        log.set_sink(lambda line: bars.console.print(line, markup=False, highlight=False))
        try:
            yield log.say
        finally:
            log.set_sink(None)
