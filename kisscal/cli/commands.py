"""The ``kisscal`` commands, each a thin layer over one function of :mod:`kisscal.session`."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Annotated, Literal

import typer

from kisscal.cli.app import (
    SessionArg,
    SessionHereArg,
    TrialArg,
    app,
    example_epilog,
    plural,
    progress_bars,
    run_verdict,
    session_package,
)
from kisscal.cli.log import say
from kisscal.errors import InputError, KisscalError


@app.command(epilog=example_epilog("kisscal demo", "kisscal demo /tmp/demo --seed 3"))
def demo(
    out: Annotated[Path, typer.Argument(help="Folder for the demo session.", metavar="DIR")] = Path(
        "kisscal-demo"
    ),
    seed: Annotated[int, typer.Option(help="Random seed of the synthetic rig.")] = 1,
) -> None:
    """Synthesise a KISS-like session and process it end to end."""
    session_package().demo(out, seed=seed, echo=say)


@app.command(
    epilog=example_epilog(
        "kisscal synth /tmp/s1 --seed 1 --fields 200",
        "kisscal synth /tmp/s2 --cameras 3",
        "kisscal synth /tmp/s3 --preset modern --seed 3 --cameras 12",
        "kisscal synth /tmp/s4 --wand 600 --wand-only",
        "kisscal synth /tmp/s6 --preset lowcost --trials walk01",
        "kisscal synth /tmp/s5 --target stepped",
    )
)
def synth(
    out: Annotated[
        Path, typer.Argument(help="Folder to write the synthetic session to.", metavar="DIR")
    ],
    preset: Annotated[
        Literal["kiss", "modern", "lowcost"],
        typer.Option(help="Kind of lab: KISS video fields, a modern ring, webcams."),
    ] = "kiss",
    seed: Annotated[int, typer.Option(help="Random seed; the same seed gives the same bytes.")] = 1,
    fields: Annotated[
        int | None,
        typer.Option(
            help="Fields in the gait trial [default: kiss 200, modern 100, lowcost 90].", min=10
        ),
    ] = None,
    cameras: Annotated[
        int | None,
        typer.Option(
            help="Number of cameras, 2 to 16 [default: kiss 6, modern 8, lowcost 4].", min=2, max=16
        ),
    ] = None,
    markers: Annotated[
        Literal[13, 15], typer.Option(help="Gait marker set: 13 or 15 markers.")
    ] = 15,
    blur_px: Annotated[
        float | None,
        typer.Option(
            help="Gaussian blur sigma in pixels [default: kiss 0.6, others per seed].", min=0
        ),
    ] = None,
    walking5: Annotated[
        bool, typer.Option(help="Also replay the real walking5.c3d trial (trial walk5).")
    ] = True,
    force: Annotated[bool, typer.Option("--force", help="Overwrite a non-empty DIR.")] = False,
    wand: Annotated[
        int,
        typer.Option(help="Fields of a wand trial wand01, with an L-frame (0: none).", min=0),
    ] = 0,
    wand_only: Annotated[
        bool, typer.Option("--wand-only", help="Calibrate from the wand and L-frame alone.")
    ] = False,
    trials: Annotated[
        str | None,
        typer.Option(
            help="Only these trials, comma-separated (walk01, stick, throw, walk5, wand01), "
            "each as in the whole session [default: all].",
            show_default=False,
        ),
    ] = None,
    target: Annotated[
        Literal["planar", "stepped"] | None,
        typer.Option(
            help="Instead: photographs of a planar or stepped dot plate, with seeds.",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Write a synthetic session with ground truth (tests, demos)."""
    session = session_package()
    if target is not None:
        session.synthesise_target(
            out, target, seed=seed, n_cameras=cameras or 3, force=force, echo=say
        )
        return
    session.synthesise(
        out,
        preset=preset,
        seed=seed,
        fields=fields,
        n_cameras=cameras,
        n_markers=markers,
        blur_px=blur_px,
        walking5=walking5,
        force=force,
        echo=say,
        wand_fields=wand,
        wand_only=wand_only,
        trials=None if trials is None else tuple(t.strip() for t in trials.split(",")),
    )


@app.command(
    epilog=example_epilog(
        "kisscal detect frames/cam1/*.png",
        "kisscal detect frames/cam1/*.png --out blobs.csv --overlay overlays/",
        "kisscal detect lab/s1/trials/walk01/cam2/*.png --session lab/s1 --camera cam2",
        "kisscal detect frames/*.tif --threshold 60 --pixel-aspect 1.0",
    )
)
def detect(
    images: Annotated[list[Path], typer.Argument(help="Image files to scan.", metavar="IMAGE...")],
    out: Annotated[Path | None, typer.Option(help="CSV file for the blob table.")] = None,
    overlay: Annotated[
        Path | None, typer.Option(help="Folder for overlay PNGs.", metavar="DIR")
    ] = None,
    session_dir: Annotated[
        Path | None,
        typer.Option(
            "--session", help="Use a camera's derived settings from this session.", metavar="DIR"
        ),
    ] = None,
    camera: Annotated[
        str | None, typer.Option(help="The session's camera (with --session).")
    ] = None,
    kind: Annotated[
        Literal["markers", "grid"],
        typer.Option(help="What the images show: markers, or the linearisation grid."),
    ] = "markers",
    threshold: Annotated[
        float | None,
        typer.Option(
            help="Threshold of a white pixel, 8-bit scale, in the terms the printed settings "
            "use: grey levels above the local background when they say so (uneven "
            "backgrounds), else the grey level itself.",
            show_default=False,
        ),
    ] = None,
    pixel_aspect: Annotated[
        float | None,
        typer.Option(
            help="Width / height of a round marker's image (1 for square pixels).",
            show_default=False,
        ),
    ] = None,
    config: Annotated[
        Path | None,
        typer.Option(help="A TOML file whose [detection] table gives settings.", metavar="FILE"),
    ] = None,
) -> None:
    """Detect marker blobs in images (a CSV table).

    Settings not given (with --threshold, --pixel-aspect, --config or a session's
    [detection]) are derived from the images themselves, or taken from a session camera's
    derived settings with --session and --camera; what was used is printed. The table
    goes to standard output, or to the file given with --out.
    """
    # the blob table's writer brings OpenCV and SciPy (kisscal.detect), the TOML reader
    # NumPy: imported when the command runs, as kisscal.session is (session_package)
    from kisscal.io.blobs import format_blobs
    from kisscal.io.toml_table import read_detection_table

    session = session_package()

    given = dict(read_detection_table(config)) if config is not None else {}
    given.update(
        {
            k: v
            for k, v in (("threshold", threshold), ("pixel_aspect", pixel_aspect))
            if v is not None
        }
    )
    tables = session.detect_images(
        images, out, overlay, given, echo=say, session=session_dir, camera=camera, kind=kind
    )
    if out is None:
        typer.echo(format_blobs(tables), nl=False)


@app.command(
    epilog=example_epilog(
        "kisscal linearise lab/2026-11-21",
        "kisscal linearise lab/2026-11-21 --camera cam2 --model similarity",
    )
)
def linearise(
    session_dir: SessionArg,
    camera: Annotated[str | None, typer.Option(help="Only this camera.")] = None,
    model: Annotated[
        Literal["homography", "similarity"] | None,
        typer.Option(
            help="Optimal grid: homography (default) or similarity (the thesis').",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Lens linearisation of each camera from its grid images."""
    with progress_bars() as echo:
        session_package().linearise(session_dir, camera=camera, model=model, echo=echo)


@app.command(
    epilog=example_epilog(
        "kisscal calibrate lab/2026-11-21",
        "kisscal calibrate lab/2026-11-21 --mdlt",
        "kisscal calibrate lab/2026-11-21 --route rods",
    )
)
def calibrate(
    session_dir: SessionArg,
    camera: Annotated[str | None, typer.Option(help="Only this camera.")] = None,
    mdlt: Annotated[
        bool | None,
        typer.Option(
            "--mdlt/--no-mdlt", help="Enforce Hatze's constraint (MDLT).", show_default=False
        ),
    ] = None,
    refine: Annotated[
        bool | None,
        typer.Option(
            "--refine/--no-refine", help="Refine by reprojection error.", show_default=False
        ),
    ] = None,
    lens: Annotated[
        bool | None,
        typer.Option("--lens/--no-lens", help="Also fit lens terms L12-L16.", show_default=False),
    ] = None,
    route: Annotated[
        str | None,
        typer.Option(
            help="Force a route: rods, wand, target or points (default: the session's).",
            show_default=False,
        ),
    ] = None,
    refresh: Annotated[
        bool,
        typer.Option(
            "--refresh",
            help="Adjust the rods with every trial the session has now, not those of its "
            "first calibration.",
        ),
    ] = False,
) -> None:
    """Calibrate every camera by the route the session describes (it says which).

    [wand] with [rods] or [axes]: wand bundle adjustment; [rods]: the rods' DLT;
    [calibration]: control points or a known target. --mdlt, --refine and --lens
    (rods and points routes) are remembered: later calibrations of the session (and
    `kisscal run`) keep them until turned off with --no-mdlt, --no-refine, --no-lens.
    The trials the rods are adjusted with are kept the same way: a walk added later
    leaves the calibration as it was until --refresh.
    """
    with progress_bars() as echo:
        session_package().calibrate(
            session_dir,
            camera=camera,
            mdlt=mdlt,
            refine=refine,
            lens=lens,
            echo=echo,
            route=route,
            refresh=refresh,
        )


@app.command(epilog=example_epilog("kisscal reconstruct lab/2026-11-21 walk01"))
def reconstruct(session_dir: SessionArg, trial: TrialArg) -> None:
    """Reconstruct 3D marker positions of a trial, field by field."""
    with progress_bars() as echo:
        session_package().reconstruct(session_dir, trial, echo=echo)


@app.command(
    epilog=example_epilog(
        "kisscal track lab/2026-11-21 walk01",
        "kisscal track lab/2026-11-21 walk01 --pnc 0.05 --sweep",
    )
)
def track(
    session_dir: SessionArg,
    trial: TrialArg,
    pnc: Annotated[
        float | None, typer.Option(help="Kalman process noise (thesis PNC).", min=0)
    ] = None,
    mnc: Annotated[
        float | None, typer.Option(help="Kalman measurement noise (thesis MNC).", min=0)
    ] = None,
    smooth: Annotated[
        bool, typer.Option("--smooth", help="GCV smoothing spline on the result.")
    ] = False,
    sweep: Annotated[
        bool, typer.Option("--sweep", help="Also write the thesis' PNC x MNC segment-length table.")
    ] = False,
) -> None:
    """Turn a trial's 3D points into labelled marker trajectories."""
    session = session_package()
    tracking: dict[str, object] = {k: v for k, v in (("pnc", pnc), ("mnc", mnc)) if v is not None}
    if smooth:
        tracking["smoothing"] = True
    overrides = session.Overrides(tracking=tracking)
    session.track(session_dir, trial, overrides=overrides, sweep=sweep, echo=say)


@app.command(
    epilog=example_epilog(
        "kisscal export lab/2026-11-21 --to pose2sim",
        "kisscal export lab/2026-11-21 --to anipose --units m",
        "kisscal export lab/2026-11-21 --to dltdv8 --out coefs.csv",
        "kisscal export lab/2026-11-21 --to opencv --out calib/",
    )
)
def export(
    session_dir: SessionArg,
    to: Annotated[
        Literal["anipose", "pose2sim", "dltdv8", "opencv"],
        typer.Option(
            help="anipose: cameras.toml; pose2sim: Pose2Sim's calibration (cam_01, ..., "
            "metres); dltdv8: 11 x n coefficient CSV in DLTdv8's pixels; opencv: one "
            "FileStorage YAML per camera."
        ),
    ],
    out: Annotated[
        Path | None,
        typer.Option(help="File (a folder for opencv) to write; default: under SESSION/out."),
    ] = None,
    units: Annotated[
        Literal["mm", "cm", "m"] | None,
        typer.Option(help="Unit of the translations (anipose, opencv; default mm)."),
    ] = None,
) -> None:
    """Write the session's calibration for another tool (after kisscal calibrate)."""
    session_package().export(session_dir, to, out, echo=say, units=units)


@app.command(
    epilog=example_epilog(
        "kisscal init lab/2026-11-21 --cameras 8", "kisscal init kiss01 --cameras 6 --preset kiss"
    )
)
def init(
    session_dir: Annotated[Path, typer.Argument(help="New session folder.", metavar="SESSION")],
    cameras: Annotated[int, typer.Option(help="Number of cameras.", min=1, max=64)] = 4,
    preset: Annotated[
        Literal["modern", "kiss", "lowcost"],
        typer.Option(help="Camera type: frame rate and image size to start from."),
    ] = "modern",
) -> None:
    """Start a session: image folders and a commented session.toml."""
    path = session_package().init_session(session_dir, cameras, preset)
    say(f"wrote {path}: fill in the lines marked FILL IN, add the images, then")
    say(f"  kisscal validate {session_dir}")


@app.command(epilog=example_epilog("kisscal validate", "kisscal validate lab/2026-11-21"))
def validate(session_dir: SessionHereArg = Path()) -> None:
    """Check every input of a session before any work; list each problem."""
    problems = session_package().validate(session_dir)
    for problem in problems:
        say(f"{'warning' if problem.warning else 'problem'}: {problem}")
    errors = [p for p in problems if not p.warning]
    if errors:  # the base class: the problems listed are of several kinds
        raise KisscalError(f"{plural(len(errors), 'problem')} found (listed above)")
    say(f"{session_dir}: every input is present and consistent")


@app.command(
    epilog=example_epilog(
        "kisscal run", "kisscal run lab/2026-11-21", "kisscal run lab/2026-11-21/session.toml"
    )
)
def run(session_dir: SessionHereArg = Path()) -> None:
    """Process the whole session, grid images to trajectories."""
    session = session_package()
    started = time.perf_counter()
    with progress_bars() as echo:
        summary = session.run(session_dir, echo=echo)
    report = session.SessionStore(session_dir).report_path
    say(run_verdict(summary, time.perf_counter() - started, report))


@app.command(
    epilog=example_epilog(
        "kisscal check lab/2026-11-21 --max-grid-px 0.08 --max-reproj-px 0.1 --max-3d-mm 1.0"
    )
)
def check(
    session_dir: SessionArg,
    max_reproj_px: Annotated[
        float | None, typer.Option(help="Limit on each camera's DLT rms_px.", metavar="PX")
    ] = None,
    max_grid_px: Annotated[
        float | None, typer.Option(help="Limit on each camera's grid residual.", metavar="PX")
    ] = None,
    max_3d_mm: Annotated[
        float | None, typer.Option(help="Limit on the leave-out 3D error.", metavar="MM")
    ] = None,
) -> None:
    """CI gate: exit 1 when a calibration figure exceeds its limit."""
    session = session_package()
    if max_reproj_px is None and max_grid_px is None and max_3d_mm is None:
        raise InputError("give at least one of --max-reproj-px, --max-grid-px, --max-3d-mm")
    failures = session.check(session_dir, max_reproj_px, max_grid_px, max_3d_mm)
    store = session.SessionStore(session_dir)
    say(f"limits written to {store.limits_path}: the report judges the session by them from now on")
    if store.report_path.is_file():
        session.report(session_dir)  # its verdicts now use these limits
        say(f"report updated: {store.report_path}")
    if failures:
        for f in failures:
            say(f"FAILED {f.camera}: {f.figure} {f.value:.4f} over the limit {f.limit:.4f}")
        say(f"FAILED check: {plural(len(failures), 'figure')} over the limit")
        raise typer.Exit(1)
    say("check passed: every figure is within its limit")


@app.command(epilog=example_epilog("kisscal report lab/2026-11-21"))
def report(session_dir: SessionArg) -> None:
    """Rebuild out/report.html of a processed session."""
    session_package().report(session_dir, echo=say)


@app.command(
    epilog=example_epilog(
        "kisscal batch lab/*", "kisscal batch lab/* --scheduler tcp://10.0.0.5:8786"
    )
)
def batch(
    sessions: Annotated[list[Path], typer.Argument(help="Session folders.", metavar="SESSION...")],
    scheduler: Annotated[
        str | None, typer.Option(help="Dask scheduler address.", metavar="ADDRESS")
    ] = None,
) -> None:
    """Run many sessions in parallel on Dask."""
    failed = session_package().batch(sessions, scheduler=scheduler, echo=say)
    if failed:
        raise typer.Exit(1)
