"""``kisscal reconstruct``: a trial's 2D blobs (or centroid files) to 3D points per field.

The stage as the runner runs it (:data:`RECONSTRUCT`): the runner resolves the trial's
blobs and keys the stage; this module turns blobs into points.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kisscal.errors import InputError
from kisscal.io.c3d import no_points, read_c3d
from kisscal.io.config import SessionConfig, TrialConfig
from kisscal.io.files import read_json, write_json
from kisscal.io.points2d import COLUMNS as POINTS2D_COLUMNS
from kisscal.io.points2d import observation_points, write_points2d
from kisscal.io.points3d import Points3DFile, write_points3d, write_trial_points
from kisscal.io.store import SessionStore, TrialFiles
from kisscal.recon import reconstruct_trial
from kisscal.recon.body import RigidTriangles
from kisscal.report.epipolar import trial_field_figure
from kisscal.rig import Rig
from kisscal.session.calibrated import current_rig
from kisscal.session.inputs import figure
from kisscal.session.progress import Echo, quiet
from kisscal.session.runner import TrialRun, TrialStage


def _inputs(run: TrialRun) -> tuple:
    """What a trial's points depend on besides its blobs; the columns: a points2d.csv of
    an older layout is redone."""
    rig = current_rig(run.root, run.echo, config=run.config)
    return rig, run.params.recon, session_body(run.config), POINTS2D_COLUMNS


def _output(files: TrialFiles) -> tuple[Path, bool]:
    return files.points3d, files.points2d.is_file()


def _cached(run: TrialRun) -> Points3DFile:
    _echo_warnings(run.trial.name, run.files.recon, run.echo)
    return run.store.points3d(run.trial.name)


def _points(run: TrialRun, inputs: tuple, blobs: dict[str, list[NDArray]]) -> Any:
    """A trial's 3D points from its blobs, written with its 2D observations, its summary
    and, for the session's first trial, the epipolar figure of its busiest field."""
    rig, recon, body, _columns = inputs
    config, trial, files, echo = run.config, run.trial, run.files, run.echo
    obs = rig.observations(blobs)
    field_idx, cam_idx, uv = obs.field, obs.camera, obs.uv_px
    t0 = time.perf_counter()
    points = reconstruct_trial(field_idx, cam_idx, uv, rig.dlts, recon, config.rate_hz, body)
    n_fields = max((len(v) for v in blobs.values()), default=0)
    summary = points.summary(n_fields, recon)
    write_trial_points(files.points3d, points, field_idx, cam_idx, config.camera_ids)
    point = observation_points(points.blob_row, len(obs))
    depth = inverse_depth_m(rig, cam_idx, point, points.xyz_mm)
    write_points2d(files.points2d, rig.ids, cam_idx, field_idx, obs.raw_px, point, depth)
    write_json(files.recon, summary)
    if len(points) and trial.name == config.trials[0].name:  # one field is enough to see
        busiest = int(np.bincount(points.field).argmax())
        sizes = [c.size_px for c in config.cameras]
        args = (points, busiest, field_idx, cam_idx, uv, rig.dlts, sizes, list(config.camera_ids))
        figure(run.root, f"epipolar_{trial.name}", trial_field_figure, *args)
    median_rms = np.median(points.rms_px) if len(points) else float("nan")
    by_n = ", ".join(f"{k} by {n}" for n, k in enumerate(summary["points_by_n_cameras"]) if k)
    echo(
        f"  reconstruct {trial.name}: {len(points)} points in {n_fields} fields"
        f"{f' ({by_n} cameras)' if by_n else ''}, median rms {median_rms:.3f} px"
        f" ({time.perf_counter() - t0:.1f} s)"
    )
    if points.stationary_test == "short":
        echo(
            f"  reconstruct {trial.name}: stationary filter not applied (trial under "
            f"{recon.stationary_min_s:g} s, or nothing moves), so reflections that stay "
            "put are kept; the cameras' LED rings are still dropped: a point that lies at a "
            "camera's centre is that camera's ring, seen by the others"
        )
    _echo_warnings(trial.name, files.recon, echo)
    return points


def _c3d(run: TrialRun) -> Points3DFile:
    return c3d_trial_points(run.config, run.trial, run.files, run.echo)


#: ``kisscal reconstruct`` as the runner runs it (:func:`kisscal.session.runner.run_trial`).
RECONSTRUCT = TrialStage("reconstruct", _inputs, _output, _cached, _points, _c3d)


def session_body(config: SessionConfig) -> RigidTriangles | None:
    """The subject's rigid triangles for reconstruction, when ``[markers]`` gives the
    subject's own ``template_mm`` and ``segments`` (a shipped set's template is scaled
    from stature, too loose for the few-millimetre test of :mod:`kisscal.recon.body`)."""
    markers = config.markers
    if markers is None or markers.template_mm is None or not markers.segments:
        return None
    return RigidTriangles.from_marker_set(markers.names, markers.template_mm, markers.segments)


def inverse_depth_m(
    rig: Rig, camera: NDArray[np.int64], point: NDArray[np.int64], xyz_mm: NDArray[np.float64]
) -> NDArray[np.float64]:
    """points2d.csv's ``weight``: 1 / the depth (m) in the observation's camera (index into
    ``rig``) of the 3D point (row of ``xyz_mm``) it went into; NaN where ``point`` is -1."""
    weight = np.full(len(point), np.nan)
    for c, cam in enumerate(rig.cameras):
        rows = np.flatnonzero((camera == c) & (point >= 0))
        weight[rows] = 1000.0 / cam.depth_mm(xyz_mm[point[rows]])
    return weight


def _echo_warnings(trial: str, recon_json: Path, echo: Echo) -> None:
    """The coverage warnings of a trial reconstructed earlier (a cached run says them too)."""
    for line in (read_json(recon_json) or {}).get("warnings", []):
        echo(f"  warning: {trial}: {line}")


def c3d_trial_points(
    config: SessionConfig, trial: TrialConfig, files: TrialFiles, echo: Echo = quiet
) -> Points3DFile:
    """A ``[[trials]] c3d`` trial: every valid marker sample of the file as an anonymous 3D
    point per field (labels and channel order are dropped: tracking and labelling start
    from scratch), written to ``points3d.csv`` (``n_cameras`` 0 and ``rms_px`` NaN: not
    known), and ``recon.json`` with the file's frames (empty ones count), its first frame
    number and the model outputs left out (see :func:`kisscal.io.c3d.read_c3d`).

    The file's frame rate must be the session's ``rate_hz``; its first frame is field 0.
    """
    source = config.root / (trial.c3d or "")
    store, path = SessionStore(config.root), files.points3d
    key = store.key("c3d-trial", [source] if source.is_file() else [])
    if store.is_current(path, key):
        echo(f"  reconstruct {trial.name}: cached")
        return store.points3d(trial.name)
    c3d = read_c3d(source)
    if not c3d.xyz_mm.shape[1]:  # before the rate: such files often give a point rate of 0
        raise InputError(f"{source}: {no_points(c3d.xyz_mm)}")
    if abs(c3d.rate_hz - config.rate_hz) > 1e-6 * c3d.rate_hz:
        raise InputError(
            f"{source}: {c3d.rate_hz:g} frames per second, but session.toml says rate_hz = "
            f"{config.rate_hz:g}"
        )
    field, channel = np.nonzero(np.isfinite(c3d.xyz_mm).all(axis=2))
    if not len(field):
        raise InputError(f"{source}: {no_points(c3d.xyz_mm)}")
    n = len(field)
    write_points3d(
        path,
        field,
        c3d.xyz_mm[field, channel],
        np.zeros(n, np.int64),
        np.full(n, np.nan),
        np.full((n, len(config.camera_ids)), -1),
        config.camera_ids,
    )
    write_json(
        files.recon,
        {
            "fields": c3d.n_frames,
            "points": n,
            "first_frame": c3d.first_frame,
            "source": source.name,
            "system": c3d.manufacturer,
            "processor": c3d.processor,
            "markers": list(c3d.labels),
            "excluded_model_outputs": list(c3d.excluded),
            "warnings": [],
        },
    )
    store.mark_current(path, key)
    system = f", {c3d.manufacturer}" if c3d.manufacturer else ""
    echo(
        f"  reconstruct {trial.name}: {n} points of {len(c3d.labels)} markers in "
        f"{c3d.n_frames} frames from {source.name} (frames {c3d.first_frame}-"
        f"{c3d.first_frame + c3d.n_frames - 1}{system})"
    )
    if c3d.excluded:
        shown = ", ".join(c3d.excluded[:12]) + (" ..." if len(c3d.excluded) > 12 else "")
        echo(
            f"  reconstruct {trial.name}: left out {len(c3d.excluded)} model outputs "
            f"(POINT:ANGLES, FORCES, MOMENTS, POWERS ..., segment axes): {shown}"
        )
    return store.points3d(trial.name)
