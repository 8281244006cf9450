"""The typer application, its shared arguments and the progress display of every command."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as package_version
from pathlib import Path
from typing import Annotated

import typer

app = typer.Typer(
    name="kisscal",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode=None,
    context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100},
)

SessionArg = Annotated[
    Path, typer.Argument(help="Session folder (holds session.toml).", metavar="SESSION")
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
) -> None:
    """Calibration and reconstruction for marker-based multi-camera gait capture.

    A session folder holds session.toml and the camera images; every output goes to its
    out/ folder. Start with `kisscal demo`, then `kisscal run SESSION` on your own.
    """


@contextlib.contextmanager
def progress_bars() -> Iterator[Callable[[str], object]]:
    """A progress bar per pipeline stage on a terminal; plain lines when output is redirected.

    Yields the function that prints the pipeline's messages (above the bars on a terminal).
    """
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    from kisscal import session

    console = Console(stderr=True)
    if not console.is_terminal:
        yield typer.echo
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

    columns = (TextColumn("{task.description:<34}"), BarColumn(), MofNCompleteColumn())
    with Progress(*columns, console=console) as bars, session.reporting_progress(Bars(bars)):
        yield lambda line: bars.console.print(line, markup=False, highlight=False)
