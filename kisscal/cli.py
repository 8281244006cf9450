"""The ``kisscal`` command line: a thin typer layer over :mod:`kisscal.session`.

Every user error is reported on one line (``kisscal <command>: ...``) with exit code 2;
``kisscal check`` exits 1 when a quality limit is exceeded.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Annotated

import typer

from kisscal.errors import KisscalError

try:  # recent typer vendors click; older releases use the click package
    from typer._click.exceptions import ClickException, UsageError
except ImportError:  # pragma: no cover
    from click.exceptions import ClickException, UsageError

app = typer.Typer(
    name="kisscal",
    help="Calibration and reconstruction for marker-based multi-camera gait capture.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

SessionArg = Annotated[Path, typer.Argument(help="Session folder (holds session.toml).")]


@contextlib.contextmanager
def progress_bars() -> Iterator[Callable[[str], object]]:
    """A progress bar per pipeline stage on a terminal; plain lines when output is redirected.

    Yields the function that prints the pipeline's messages (above the bars on a terminal).
    """
    from kisscal import session

    try:
        from rich.console import Console
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn
    except ImportError:  # pragma: no cover - rich comes with typer
        yield typer.echo
        return
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


@app.command()
def demo(
    out: Annotated[Path, typer.Argument(help="Folder for the demo session.")] = Path(
        "kisscal-demo"
    ),
    seed: Annotated[int, typer.Option(help="Random seed of the synthetic rig.")] = 1,
) -> None:
    """Synthesise a KISS-like session and process it end to end."""
    from kisscal import session

    session.demo(out, seed=seed, echo=typer.echo)


@app.command()
def synth(
    out: Annotated[Path, typer.Argument(help="Folder to write the synthetic session to.")],
    seed: Annotated[int, typer.Option(help="Random seed; the same seed gives the same bytes.")] = 1,
    fields: Annotated[int, typer.Option(help="Fields in the gait trial (50 Hz).", min=10)] = 200,
    cameras: Annotated[int, typer.Option(help="Number of cameras (2 to 6).", min=2, max=6)] = 6,
    markers: Annotated[int, typer.Option(help="Gait marker set: 13 or 15 markers.")] = 15,
    blur_px: Annotated[float, typer.Option(help="Gaussian blur sigma in pixels.", min=0)] = 0.6,
    walking5: Annotated[
        bool, typer.Option(help="Also replay the real walking5.c3d trial if it is found.")
    ] = True,
    force: Annotated[bool, typer.Option(help="Overwrite a non-empty OUT folder.")] = False,
) -> None:
    """Write a synthetic KISS-like session (images + truth) for tests and demos."""
    from kisscal import session

    session.synthesise(
        out,
        seed=seed,
        fields=fields,
        n_cameras=cameras,
        n_markers=markers,
        blur_px=blur_px,
        walking5=walking5,
        force=force,
        echo=typer.echo,
    )


@app.command()
def detect(
    images: Annotated[list[Path], typer.Argument(help="Image files to scan.")],
    out: Annotated[Path | None, typer.Option(help="CSV file for the blob table.")] = None,
    overlay: Annotated[Path | None, typer.Option(help="Folder for overlay PNGs.")] = None,
) -> None:
    """Detect marker blobs in images and write their centroids."""
    from kisscal import session

    session.detect_images(images, out, overlay, echo=typer.echo)


@app.command()
def linearise(
    session_dir: SessionArg,
    camera: Annotated[str | None, typer.Option(help="Only this camera.")] = None,
    model: Annotated[
        str | None,
        typer.Option(help="Optimal grid: homography (default) or similarity (the thesis')."),
    ] = None,
) -> None:
    """Fit each camera's lens linearisation from its dot-grid images."""
    from kisscal import session

    with progress_bars() as echo:
        session.linearise(session_dir, camera=camera, model=model, echo=echo)


@app.command()
def calibrate(
    session_dir: SessionArg,
    camera: Annotated[str | None, typer.Option(help="Only this camera.")] = None,
    mdlt: Annotated[bool, typer.Option(help="Enforce Hatze's constraint (MDLT).")] = False,
    refine: Annotated[bool, typer.Option(help="Refine by reprojection error.")] = False,
    lens: Annotated[bool, typer.Option(help="Also fit lens terms L12-L16.")] = False,
) -> None:
    """Compute each camera's DLT parameters from the rod images."""
    from kisscal import session

    with progress_bars() as echo:
        session.calibrate(
            session_dir, camera=camera, mdlt=mdlt, refine=refine, lens=lens, echo=echo
        )


@app.command()
def reconstruct(
    session_dir: SessionArg,
    trial: Annotated[str, typer.Argument(help="Trial name from session.toml.")],
) -> None:
    """Reconstruct 3D marker positions of a trial, field by field."""
    from kisscal import session

    with progress_bars() as echo:
        session.reconstruct(session_dir, trial, echo=echo)


@app.command()
def track(
    session_dir: SessionArg,
    trial: Annotated[str, typer.Argument(help="Trial name from session.toml.")],
    pnc: Annotated[float | None, typer.Option(help="Kalman process noise (thesis PNC).")] = None,
    mnc: Annotated[
        float | None, typer.Option(help="Kalman measurement noise (thesis MNC).")
    ] = None,
    smooth: Annotated[bool, typer.Option(help="GCV smoothing spline on the result.")] = False,
    sweep: Annotated[
        bool, typer.Option(help="Also write the thesis' PNC x MNC segment-length table.")
    ] = False,
) -> None:
    """Turn a trial's 3D points into labelled marker trajectories."""
    from kisscal import session

    tracking = {k: v for k, v in (("pnc", pnc), ("mnc", mnc)) if v is not None}
    if smooth:
        tracking["smoothing"] = True
    overrides = session.Overrides(tracking=tracking)
    session.track(session_dir, trial, overrides=overrides, sweep=sweep, echo=typer.echo)


@app.command()
def run(session_dir: SessionArg) -> None:
    """Run the whole session: detect, linearise, calibrate, reconstruct, track."""
    from kisscal import session

    with progress_bars() as echo:
        session.run(session_dir, echo=echo)


@app.command()
def check(
    session_dir: SessionArg,
    max_reproj_px: Annotated[float | None, typer.Option(help="Limit on DLT rms_px.")] = None,
    max_grid_px: Annotated[float | None, typer.Option(help="Limit on grid residual.")] = None,
    max_3d_mm: Annotated[float | None, typer.Option(help="Limit on leave-out 3D error.")] = None,
) -> None:
    """CI gate: exit 1 when a camera's residuals exceed the limits."""
    from kisscal import session

    if max_reproj_px is None and max_grid_px is None and max_3d_mm is None:
        raise KisscalError(
            "kisscal check: give at least one of --max-reproj-px, --max-grid-px, --max-3d-mm"
        )
    failures = session.check(session_dir, max_reproj_px, max_grid_px, max_3d_mm)
    if failures:
        typer.echo(f"{'camera':<8} {'figure':<28} {'value':>10} {'limit':>10}")
        for f in failures:
            typer.echo(f"{f.camera:<8} {f.figure:<28} {f.value:>10.4f} {f.limit:>10.4f}")
        raise typer.Exit(1)
    typer.echo("check passed: every figure is within its limit")


@app.command()
def report(session_dir: SessionArg) -> None:
    """Rebuild the session report (out/report.html)."""
    from kisscal import session

    session.report(session_dir, echo=typer.echo)


@app.command()
def batch(
    sessions: Annotated[list[Path], typer.Argument(help="Session folders.")],
    scheduler: Annotated[str | None, typer.Option(help="Dask scheduler address.")] = None,
) -> None:
    """Run many sessions in parallel on Dask."""
    from kisscal import session

    failed = session.batch(sessions, scheduler=scheduler, echo=typer.echo)
    if failed:
        raise typer.Exit(1)


def main(argv: list[str] | None = None) -> None:
    """Entry point: run the typer app, turning every user error into one line.

    Usage errors (a missing argument, a bad number) and :class:`KisscalError` from any
    stage are printed as ``kisscal: error: ...`` with exit code 2, never as a traceback.
    """
    args = sys.argv[1:] if argv is None else argv
    try:
        rv = app(args=args or ["--help"], prog_name="kisscal", standalone_mode=False)
    except UsageError as exc:
        where = f"kisscal {exc.ctx.info_name}" if exc.ctx and exc.ctx.parent else "kisscal"
        typer.echo(f"{where}: error: {exc.format_message()}", err=True)
        sys.exit(2)
    except KisscalError as exc:
        typer.echo(f"kisscal: error: {exc}", err=True)
        sys.exit(exc.exit_code)
    except OSError as exc:  # a path the user gave cannot be read or written
        where = f": {exc.filename}" if exc.filename else ""
        typer.echo(f"kisscal: error: {exc.strerror or exc}{where}", err=True)
        sys.exit(2)
    except ClickException as exc:
        typer.echo(f"kisscal: error: {exc.format_message()}", err=True)
        sys.exit(exc.exit_code)
    sys.exit(rv if isinstance(rv, int) else 0)


if __name__ == "__main__":
    main()
