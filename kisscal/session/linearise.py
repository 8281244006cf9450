"""``kisscal linearise``: each camera's lens linearisation from its dot-grid frames."""

from __future__ import annotations

import dataclasses
import functools
import json
import time
from collections.abc import Sequence
from pathlib import Path

from kisscal.detect import DetectionParams
from kisscal.errors import InputError, KisscalError, with_context
from kisscal.grid import GridFit, Linearisation, identity_linearisation, linearise_frames
from kisscal.io.config import CameraConfig, SessionConfig
from kisscal.io.files import write_text
from kisscal.io.frames import camera_frames, source_files
from kisscal.io.linearisation import (
    grid_fit_of,
    read_linearisation,
    refined_by,
    write_linearisation,
)
from kisscal.io.store import SessionStore
from kisscal.report.grid import grid_correction_figure
from kisscal.session.inputs import figure, select_cameras, writes_session
from kisscal.session.params import Overrides, StageParams, stage_params
from kisscal.session.progress import Echo, Progress, quiet, reporting_progress, steps
from kisscal.session.routes.imported import imported_linearisation
from kisscal.session.runner import camera_detection, each_camera, run_keyed
from kisscal.session.trials import SizedFrames


@writes_session
def linearise(
    root: Path,
    camera: str | None = None,
    model: str | None = None,
    overrides: Overrides | None = None,
    echo: Echo = quiet,
    workers: int | None = None,
    *,
    config: SessionConfig,
) -> dict[str, Linearisation]:
    """``kisscal linearise``: each camera's linearisation from its grid frames.

    Cameras are fitted side by side in ``workers`` processes (default: one per core).

    Writes ``out/linearisation/<camera>.json`` and returns ``{camera: Linearisation}``.
    A session without ``[grid]`` gets the identity linearisation; one calibrated by
    ``[calibration] cameras`` the polynomial fitted to that file's OpenCV distortion.
    ``config`` is the session's, read from ``root`` when the caller has none
    (:func:`~kisscal.session.inputs.loads_config`).
    """
    o = overrides or Overrides()
    if model is not None:
        o = dataclasses.replace(o, grid={**o.grid, "model": model})
    params = stage_params(config, o)
    cameras = select_cameras(config, camera)
    if config.calibration is not None and config.calibration.route == "cameras":
        return {c.id: imported_linearisation(config, c, echo) for c in steps(cameras, "linearise")}
    if config.grid is None:
        return {c.id: _identity(c) for c in cameras}

    kept = _all_cached(Path(root), config, params, cameras, echo)
    if kept is not None:
        return kept
    # a partial of a module-level function: spawned workers (Windows) receive it pickled
    fit = functools.partial(_linearise_camera, Path(root), config, params)
    fits = each_camera(fit, cameras, "linearise", echo, workers)
    return {c.id: lin for c, lin in zip(cameras, fits, strict=True)}


def _all_cached(
    root: Path,
    config: SessionConfig,
    params: StageParams,
    cameras: Sequence[CameraConfig],
    echo: Echo,
) -> dict[str, Linearisation] | None:
    """Every camera's linearisation read from its cache, here; None when one of them is
    not current (all are then fitted or read side by side, :func:`each_camera`).

    The later stages ask for the linearisations a dozen times a session (every
    :func:`~kisscal.session.calibrated.current_rig`): a pool of processes started only
    to find the caches current cost more than the check. Checked only where every
    camera's linearisation and detection settings were written: else the check itself
    would derive the grid's detection settings here, one camera after the other.
    """
    store = SessionStore(root)
    written = (store.linearisation_path(c.id) for c in cameras)
    surveyed = (store.detection_path(c.id) for c in cameras)
    if not all(p.is_file() for p in (*written, *surveyed)):
        return None
    kept = {}
    for cam in cameras:
        try:
            stage = _grid_inputs(config, params, cam, echo)[2]
        except KisscalError:  # said by the cameras' own processes, the others done
            return None
        read = functools.partial(_read, store, cam.id)
        lin = run_keyed(store, store.linearisation_path(cam.id), stage, read)
        if lin is None:
            return None
        kept[cam.id] = lin
    for cam in cameras:
        echo(f"  linearise {cam.id}: cached")
    return kept


def _identity(cam: CameraConfig) -> Linearisation:
    """No grid: the identity linearisation, normalised about the image centre.

    A camera of a session without images (``[calibration] points``, no ``size``) has no
    known centre; the identity does not need one (it leaves every coordinate unchanged
    whatever the normalisation), so it is normalised about the pixel origin.
    """
    if cam.size_px is None:
        return identity_linearisation((0.0, 0.0), 1.0)
    w, h = cam.size_px
    return identity_linearisation(((w - 1) / 2, (h - 1) / 2), (w - 1) / 2)


def _linearise_camera(
    root: Path, config: SessionConfig, params: StageParams, cam: CameraConfig, echo: Echo
) -> Linearisation:
    """One camera's linearisation: from the cache, or fitted and written with its figure
    (the camera last, as :func:`each_camera` calls it)."""
    store = SessionStore(root)
    out = store.linearisation_path(cam.id)
    frames, detection, stage = _grid_inputs(config, params, cam, echo)

    def cached() -> Linearisation:
        echo(f"  linearise {cam.id}: cached")
        return _read(store, cam.id)

    def compute() -> Linearisation:
        t0 = time.perf_counter()
        try:
            sized = list(SizedFrames(frames, cam.id, cam.size_px))
            fit = linearise_frames(sized, params.grid, detection)
        except KisscalError as exc:
            raise with_context(exc, f"camera {cam.id} grid: ") from None
        lin, index = fit.linearisation, fit.index
        write_linearisation(out, lin, cam.id, index.missing_rc, index.missing_uv)
        figure(root, f"grid_{cam.id}", grid_correction_figure, fit, cam.id, cam.size_px)
        _say_fitted(echo, cam.id, fit, time.perf_counter() - t0)
        return lin

    return run_keyed(store, out, stage, cached, compute)


def _grid_inputs(
    config: SessionConfig, params: StageParams, cam: CameraConfig, echo: Echo
) -> tuple[Sequence, DetectionParams, tuple]:
    """A camera's grid frames, their detection settings and what its linearisation is
    keyed on (:func:`~kisscal.session.runner.run_keyed`)."""
    if config.grid is None:
        raise InputError(f"{config.path}: camera {cam.id} has no [grid] to linearise from")
    frames = camera_frames(
        config.root, config.grid.images, cam.id, "grid", fields=config.grid.fields
    )
    detection = camera_detection(config, cam, "grid", params, echo)
    stage = ("linearise", source_files(frames), config.grid.fields, params.grid, detection)
    return frames, detection, stage


def _read(store: SessionStore, camera: str) -> Linearisation:
    """A camera's linearisation as its stage wrote it."""
    doc, out = store.linearisation_doc(camera), store.linearisation_path(camera)
    grid = grid_fit_of(doc, str(out)) if doc is not None else None
    return grid if grid is not None else read_linearisation(out)[1]


def _say_fitted(echo: Echo, camera: str, fit: GridFit, seconds: float) -> None:
    q = fit.linearisation.quality
    echo(
        f"  linearise {camera}: {q.dots_used} dots, residual {q.residual_rms_after_px:.3f} px, "
        f"straightness {q.straightness_rms_before_px:.2f} -> "
        f"{q.straightness_rms_after_px:.3f} px ({seconds:.1f} s)"
    )
    for warning in fit.warnings():
        echo(f"  warning: {camera}: {warning}")


def grid_linearisations(config: SessionConfig, echo: Echo) -> dict[str, Linearisation]:
    """Each camera's grid linearisation (identity without a grid; an imported camera's
    lens), fitted if missing or stale: what a calibration route starts from.

    It stays quiet about linearisations that are already current.
    """

    def news(line: str) -> None:
        if not line.endswith("cached"):
            echo(line)

    with reporting_progress(Progress()):
        return linearise(config.root, echo=news, config=config)


def current_linearisations(config: SessionConfig, echo: Echo) -> dict[str, Linearisation]:
    """The linearisation every camera's DLT goes with: the grid's, or the one a
    calibration route estimated (a wand's lens terms) and wrote in its place."""
    lins = grid_linearisations(config, echo)
    store = SessionStore(config.root)
    for cam in lins:
        if refined_by(store.linearisation_doc(cam)) is not None:
            lins[cam] = store.linearisation(cam)
    return lins


def restore_grid_linearisations(root: Path, cameras: Sequence[str], route: str) -> None:
    """Put back the grid's linearisation where another route than ``route`` refined it.

    Called after a calibration route succeeded: its DLTs go with the grid's linearisation
    (or with none, without a grid), not with an earlier route's lens estimate.
    """
    store = SessionStore(root)
    for cam in cameras:
        path = store.linearisation_path(cam)
        doc = store.linearisation_doc(cam)
        by = refined_by(doc)
        if doc is None or by is None or by == route:
            continue
        grid = doc["refined"].get("grid_fit")
        if grid is None:
            path.unlink()
        else:
            write_text(path, json.dumps(grid, indent=2) + "\n")
