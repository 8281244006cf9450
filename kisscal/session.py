"""Runs a lab session: one stage calling the next, reading and writing through :mod:`kisscal.io`.

The stages (:mod:`kisscal.detect`, :mod:`kisscal.grid`, :mod:`kisscal.dlt`,
:mod:`kisscal.recon`, :mod:`kisscal.tracking`) work on arrays; this module finds their
inputs in the session folder, caches their results under ``out/cache`` keyed by a hash of
inputs and parameters, and writes every output atomically. The CLI is a thin layer over
the functions here; tests call them directly.
"""

from __future__ import annotations

import contextlib
import contextvars
import dataclasses
import difflib
import os
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.errors import KisscalError

Echo = Callable[[str], object]


def _quiet(_: str) -> None:
    return None


class Progress:
    """Where the pipeline reports how far a stage has got; the base class ignores it.

    The CLI installs a progress bar with :func:`reporting_progress`; library calls and
    tests stay silent. Like logging, this is set for the running context rather than passed
    through every stage call.
    """

    def start(self, stage: str, total: int) -> None:
        """A stage of ``total`` steps begins."""

    def advance(self, steps: int = 1) -> None:
        """Steps of the current stage are done."""


_PROGRESS: contextvars.ContextVar[Progress | None] = contextvars.ContextVar(
    "kisscal_progress", default=None
)


def _steps(items: Sequence[Any], stage: str) -> Iterator[Any]:
    """Iterate over ``items``, reporting each one done (after its loop body) as a step."""
    progress = _PROGRESS.get() or Progress()
    items = list(items)
    progress.start(stage, len(items))
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


# ----------------------------------------------------------------------------- params


@dataclass(frozen=True)
class Overrides:
    """Parameter overrides from the command line, per stage (``{"pnc": 0.05}`` ...)."""

    detection: Mapping[str, Any] = field(default_factory=dict)
    grid: Mapping[str, Any] = field(default_factory=dict)
    dlt: Mapping[str, Any] = field(default_factory=dict)
    recon: Mapping[str, Any] = field(default_factory=dict)
    tracking: Mapping[str, Any] = field(default_factory=dict)


def _params(cls: type, section: str, *layers: Mapping[str, Any], ignore: Sequence[str] = ()) -> Any:
    """Build a stage's parameter dataclass from config/CLI layers; unknown keys are errors."""
    from kisscal.params import Params

    if issubclass(cls, Params):
        return cls.from_layers(*layers, ignore=ignore)
    names = {f.name: f for f in dataclasses.fields(cls)}
    values: dict[str, Any] = {}
    for layer in layers:
        for key, value in layer.items():
            if key in ignore:
                continue
            if key not in names:
                close = difflib.get_close_matches(key, list(names), n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise KisscalError(f"[{section}] unknown parameter {key!r}{hint}")
            if isinstance(value, list):
                value = tuple(value)
            values[key] = value
    try:
        return cls(**values)
    except (TypeError, ValueError) as exc:
        raise KisscalError(f"[{section}] {exc}") from None


@dataclass(frozen=True)
class StageParams:
    """Every stage's parameters for one session (defaults <- session.toml <- CLI)."""

    detection: Any
    grid: Any
    dlt: Any
    recon: Any
    tracking: Any


def stage_params(config: Any, overrides: Overrides | None = None) -> StageParams:
    """Parameters of every stage from ``session.toml`` sections and CLI overrides."""
    from kisscal.detect import DetectionParams
    from kisscal.dlt import DltParams
    from kisscal.grid import GridParams
    from kisscal.recon import ReconParams
    from kisscal.tracking import TrackingParams

    o = overrides or Overrides()
    grid_cfg = {}
    if config.grid is not None:
        grid_cfg = {"rows": config.grid.rows, "cols": config.grid.cols}
        grid_cfg.update(config.sections.get("grid", {}))
    return StageParams(
        detection=_params(DetectionParams, "detection", config.detection, o.detection),
        grid=_params(GridParams, "grid", grid_cfg, o.grid),
        dlt=_params(DltParams, "dlt", config.sections.get("dlt", {}), o.dlt),
        recon=_params(ReconParams, "recon", config.sections.get("recon", {}), o.recon),
        tracking=_params(
            TrackingParams, "tracking", config.sections.get("tracking", {}), o.tracking
        ),
    )


# ------------------------------------------------------------------------------ paths


def out_dir(root: Path) -> Path:
    return Path(root) / "out"


def _load(root: Path) -> Any:
    from kisscal.io.config import load_session

    return load_session(Path(root))


# -------------------------------------------------------------------------- detection


def _detect_frames(
    frames: Sequence[np.ndarray],
    params: Any,
    cache_file: Path,
    key: str,
    echo: Echo,
    what: str,
    workers: int | None = None,
) -> list:
    """Blobs of every frame, from the cache when its key matches."""
    from kisscal.detect import detect_sequence
    from kisscal.io.cache import is_current, load_blob_frames, mark_current, save_blob_frames

    if is_current(cache_file, key):
        echo(f"  detect {what}: {len(frames)} frames (cached)")
        return load_blob_frames(cache_file)
    t0 = time.perf_counter()
    blobs = detect_sequence(frames.__getitem__, params, count=len(frames), workers=workers)
    save_blob_frames(cache_file, blobs)
    mark_current(cache_file, key)
    echo(f"  detect {what}: {len(frames)} frames in {time.perf_counter() - t0:.1f} s")
    return blobs


def detect_images(
    paths: Sequence[Path],
    out_csv: Path | None = None,
    overlay_dir: Path | None = None,
    detection: Mapping[str, Any] | None = None,
    echo: Echo = _quiet,
) -> int:
    """``kisscal detect``: blobs of image files to one CSV, overlays optionally.

    Returns the number of blobs found. Every image is read and checked before anything
    is written, so a bad file leaves earlier outputs untouched.
    """
    from kisscal.detect import DetectionParams, detect_sequence
    from kisscal.io.blobs import write_blobs
    from kisscal.io.frames import read_image

    params = _params(DetectionParams, "detection", detection or {})
    images = [read_image(p) for p in paths]
    blobs = detect_sequence(images, params)
    if out_csv is not None:
        write_blobs(out_csv, [(str(p), b) for p, b in zip(paths, blobs, strict=True)])
    if overlay_dir is not None:
        import cv2

        from kisscal.io.files import write_bytes
        from kisscal.report.overlay import draw_overlay

        for k, (p, image, b) in enumerate(zip(paths, images, blobs, strict=True)):
            rgb = draw_overlay(image, b)
            _ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
            # numbered and with the folder: frames of different cameras share file names
            name = f"{k:04d}_{Path(p).parent.name}_{Path(p).stem}_overlay.png"
            write_bytes(Path(overlay_dir) / name, buf.tobytes())
    total = sum(len(b) for b in blobs)
    valid = sum(int(b.valid.sum()) for b in blobs)
    echo(f"{len(paths)} images: {total} blobs ({valid} valid)")
    return total


# ---------------------------------------------------------------------- linearisation


def linearise(
    root: Path,
    camera: str | None = None,
    model: str | None = None,
    overrides: Overrides | None = None,
    echo: Echo = _quiet,
) -> dict[str, Any]:
    """``kisscal linearise``: each camera's linearisation from its grid frames.

    Writes ``out/linearisation/<camera>.json`` and returns ``{camera: Linearisation}``.
    A session without ``[grid]`` gets the identity linearisation.
    """
    from kisscal.io.cache import cache_key, is_current, mark_current
    from kisscal.io.frames import camera_frames
    from kisscal.io.linearisation import read_linearisation, write_linearisation

    config = _load(root)
    o = overrides or Overrides()
    if model is not None:
        o = dataclasses.replace(o, grid={**o.grid, "model": model})
    params = stage_params(config, o)
    cameras = _select_cameras(config, camera)
    result = {}
    for cam in _steps(cameras, "linearise"):
        out = out_dir(root) / "linearisation" / f"{cam.id}.json"
        if config.grid is None:
            from kisscal.grid import identity_linearisation

            w, h = cam.size_px
            result[cam.id] = identity_linearisation(((w - 1) / 2, (h - 1) / 2), (w - 1) / 2)
            continue
        frames = camera_frames(config.root, config.grid.images, cam.id, "grid")
        key = cache_key(
            "linearise", _file_keys(frames.paths, config.root), params.grid, params.detection
        )
        if is_current(out, key):
            result[cam.id] = read_linearisation(out)[1]
            echo(f"  linearise {cam.id}: cached")
            continue
        from kisscal.grid import linearise_frames

        t0 = time.perf_counter()
        try:
            fit = linearise_frames(list(frames), params.grid, params.detection)
        except KisscalError as exc:
            raise KisscalError(f"camera {cam.id} grid: {exc}") from None
        write_linearisation(
            out, fit.linearisation, cam.id, fit.index.missing_rc, fit.index.missing_uv
        )
        _figure(
            root,
            f"grid_{cam.id}",
            "kisscal.report.grid",
            "grid_correction_figure",
            fit,
            cam.id,
            cam.size_px,
        )
        mark_current(out, key)
        lin = fit.linearisation
        q = lin.quality
        echo(
            f"  linearise {cam.id}: {q.dots_used} dots, residual {q.residual_rms_after_px:.3f} px, "
            f"straightness {q.straightness_rms_before_px:.2f} -> "
            f"{q.straightness_rms_after_px:.3f} px "
            f"({time.perf_counter() - t0:.1f} s)"
        )
        for warning in fit.warnings():
            echo(f"  warning: {cam.id}: {warning}")
        result[cam.id] = lin
    return result


def _select_cameras(config: Any, camera: str | None) -> tuple:
    if camera is None:
        return config.cameras
    for cam in config.cameras:
        if cam.id == camera:
            return (cam,)
    close = difflib.get_close_matches(camera, list(config.camera_ids), n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    raise KisscalError(f"no camera {camera!r} in {config.path}{hint}")


def _linearisations(root: Path, config: Any, echo: Echo) -> dict[str, Any]:
    """The current linearisation of every camera (computing what is missing or stale).

    Later stages call this; it stays quiet about linearisations that are already current.
    """

    def news(line: str) -> None:
        if not line.endswith("cached"):
            echo(line)

    with reporting_progress(Progress()):
        return linearise(root, echo=news)


# ------------------------------------------------------------------------ calibration


def calibrate(
    root: Path,
    camera: str | None = None,
    mdlt: bool = False,
    refine: bool = False,
    lens: bool = False,
    overrides: Overrides | None = None,
    echo: Echo = _quiet,
    workers: int | None = None,
) -> dict[str, Any]:
    """``kisscal calibrate``: DLT parameters of each camera from rods or control points.

    Writes ``out/dlt/<camera>.json`` and ``out/dlt/dltdv.csv``; returns
    ``{camera: DltResult}`` plus the leave-one-rod-out check under ``"_check"``.
    """
    from kisscal.grid import apply_linearisation
    from kisscal.io.dltfiles import read_control_points_csv, write_dlt_json, write_dltdv_csv
    from kisscal.io.files import write_json

    config = _load(root)
    o = overrides or Overrides()
    switches = {k: v for k, v in (("mdlt", mdlt), ("refine", refine), ("lens", lens)) if v}
    o = dataclasses.replace(o, dlt={**o.dlt, **switches})
    params = stage_params(config, o)
    lins = _linearisations(root, config, echo)
    cameras = _select_cameras(config, camera)
    out = out_dir(root) / "dlt"
    summary: dict[str, Any] = {}
    if config.rods is not None:
        import json

        from kisscal.dlt import calibrate_rods, make_rods
        from kisscal.io.cache import cache_key, is_current, mark_current
        from kisscal.io.dltfiles import write_dlt_outputs
        from kisscal.io.frames import camera_frames

        rods = make_rods([(r.name, r.points_mm) for r in config.rods.rods])
        rod_frames = {
            cam.id: camera_frames(config.root, config.rods.images, cam.id, "rod") for cam in cameras
        }
        stage_key = cache_key(
            "calibrate",
            {c: _file_keys(f.paths, config.root) for c, f in rod_frames.items()},
            _linearisation_key({c: lins[c] for c in rod_frames}),
            params.detection,
            params.dlt,
            [(r.name, r.points_mm) for r in config.rods.rods],
        )
        if camera is None and is_current(out / "check.json", stage_key):
            echo("  calibrate: cached (rod images, linearisation and parameters unchanged)")
            return {"_check": json.loads((out / "check.json").read_text())}
        blobs_px = {}
        for cam in _steps(cameras, "calibrate: detect rods"):
            frames = rod_frames[cam.id]
            key = cache_key("detect", _file_keys(frames.paths, config.root), params.detection)
            cache = out_dir(root) / "cache" / "blobs" / f"rods-{cam.id}.npz"
            frame_blobs = _detect_frames(
                frames, params.detection, cache, key, echo, f"rods {cam.id}", workers
            )
            blobs_px[cam.id] = [
                apply_linearisation(lins[cam.id], b.valid_only().xy_px) for b in frame_blobs
            ]
        t0 = time.perf_counter()
        cal = calibrate_rods(blobs_px, rods, params.dlt, leave_one_out=camera is None)
        write_dlt_outputs(out, cal)
        rig = {k: v for k, v in cal.summary().items() if k != "cameras"}
        if camera is None:
            write_json(out / "check.json", rig)
            mark_current(out / "check.json", stage_key)
            summary["_check"] = rig
        for cam_id, res in cal.results.items():
            summary[cam_id] = res
            echo(
                f"  calibrate {cam_id}: {res.method}, {len(res.residuals_px)} rod markers, "
                f"rms {res.rms_px:.3f} px, centre {np.round(res.centre_mm).tolist()} mm"
                + (
                    f", missing {', '.join(cal.matches[cam_id].missing)}"
                    if cal.matches[cam_id].missing
                    else ""
                )
            )
        if "rods_in_sample_mean_mm" in rig:
            loo = rig.get("leave_one_rod_out", {})
            echo(
                f"  rods reconstructed in-sample: mean {rig['rods_in_sample_mean_mm']:.3f} mm"
                + (f"; leave-one-rod-out mean {loo['mean_mm']:.3f} mm" if loo else "")
                + f" ({time.perf_counter() - t0:.1f} s)"
            )
        sizes = {c.id: c.size_px for c in config.cameras}
        from kisscal.report.dlt import CameraResiduals

        residuals = {
            c: CameraResiduals(cal.control_uv_px[c], r.residuals_px, sizes[c], r.rms_px)
            for c, r in cal.results.items()
        }
        _figure(root, "dlt_residuals", "kisscal.report.dlt", "residual_figure", residuals)
        _figure(
            root,
            "rig",
            "kisscal.report.dlt",
            "rig_figure",
            {c: r.centre_mm for c, r in cal.results.items()},
            [(r.name, r.points_mm) for r in rods],
            {c: r.R for c, r in cal.results.items()},
        )
    elif config.calibration is not None:
        from kisscal.dlt import calibrate_camera

        for cam in cameras:
            path = config.root / config.calibration.points.replace("{camera}", cam.id)
            uv_raw, xyz, labels = read_control_points_csv(path)
            uv = apply_linearisation(lins[cam.id], uv_raw)
            res = calibrate_camera(xyz, uv, params.dlt, cam.id)
            write_dlt_json(out / f"{cam.id}.json", cam.id, res, xyz, uv, labels)
            summary[cam.id] = res
            echo(
                f"  calibrate {cam.id}: {res.method}, {len(xyz)} control points, "
                f"rms {res.rms_px:.3f} px"
            )
    else:
        raise KisscalError(
            f"{config.path}: no [rods] and no [calibration]: nothing to calibrate from"
        )
    all_L = _read_dlts(root, config, required=False)
    write_dltdv_csv(out / "dltdv.csv", {c: all_L[c] for c in config.camera_ids if c in all_L})
    return summary


def _linearisation_key(lins: Mapping[str, Any]) -> dict[str, tuple]:
    """What of each camera's linearisation a cache key depends on."""
    return {c: (lin.x, lin.y, lin.center_px, lin.scale_px) for c, lin in lins.items()}


def _file_keys(paths: Sequence[Path], root: Path) -> list[tuple[str, int, int]]:
    """Input files for a cache key: path inside the session, size and modification time.

    Paths are relative so that a copied or moved session keeps its cache.
    """
    keys = []
    for p in paths:
        st = Path(p).stat()
        keys.append((Path(p).relative_to(root).as_posix(), st.st_size, st.st_mtime_ns))
    return keys


def _read_dlts(root: Path, config: Any, required: bool = True) -> dict[str, np.ndarray]:
    from kisscal.io.dltfiles import read_dlt_json

    result = {}
    for cam in config.camera_ids:
        path = out_dir(root) / "dlt" / f"{cam}.json"
        if path.is_file():
            result[cam] = read_dlt_json(path).L
        elif required:
            raise KisscalError(f"{path}: missing; run `kisscal calibrate {root}` first")
    return result


# --------------------------------------------------------------------- reconstruction


def _trial_input_keys(config: Any, trial: Any) -> dict[str, Any]:
    """Per camera, the files a trial's 2D data come from (for cache keys)."""
    from kisscal.io.frames import trial_frames

    if trial.source == "centroids":
        paths = {
            c: [config.root / trial.centroids.replace("{camera}", c)] for c in config.camera_ids
        }
    else:
        pattern = trial.images or trial.video
        frames = trial_frames(
            config.root, pattern, config.camera_ids, trial.name, video=trial.source == "video"
        )
        paths = {c: list(f.paths) if hasattr(f, "paths") else [f.path] for c, f in frames.items()}
    for c, ps in paths.items():
        for p in ps:
            if not p.is_file():
                raise KisscalError(f"{p}: file of trial {trial.name!r}, camera {c}, not found")
    return {c: _file_keys(ps, config.root) for c, ps in paths.items()}


def _trial_blobs(
    root: Path,
    config: Any,
    trial: Any,
    params: StageParams,
    echo: Echo,
    workers: int | None = None,
) -> dict[str, list]:
    """Per camera, the raw (distorted) valid blob centroids of every field, as (n, 2) arrays."""
    from kisscal.io.cache import cache_key
    from kisscal.io.frames import trial_frames

    if trial.source == "centroids":
        from kisscal.io.files import read_table

        out = {}
        for cam in config.camera_ids:
            path = config.root / trial.centroids.replace("{camera}", cam)
            table = read_table(path, required=("field", "x_px", "y_px"))
            f = table["field"].astype(int)
            if len(f) and f.min() < 0:
                raise KisscalError(f"{path}: field numbers must be 0 or more")
            n = int(f.max()) + 1 if len(f) else 0
            xy = np.column_stack([table["x_px"], table["y_px"]])
            out[cam] = [xy[f == i] for i in range(n)]
        counts = {c: len(v) for c, v in out.items()}
        n_fields = max(counts.values())
        return {c: v + [np.zeros((0, 2))] * (n_fields - len(v)) for c, v in out.items()}
    pattern = trial.images or trial.video
    frames = trial_frames(
        config.root, pattern, config.camera_ids, trial.name, video=trial.source == "video"
    )
    out = {}
    for cam, seq in _steps(list(frames.items()), f"reconstruct {trial.name}: detect"):
        inputs = list(seq.paths) if hasattr(seq, "paths") else [seq.path]
        key = cache_key("detect", _file_keys(inputs, config.root), params.detection)
        cache = out_dir(root) / "cache" / "blobs" / f"trial-{trial.name}-{cam}.npz"
        blobs = _detect_frames(
            seq, params.detection, cache, key, echo, f"{trial.name} {cam}", workers
        )
        out[cam] = [b.valid_only().xy_px for b in blobs]
    return out


def reconstruct(
    root: Path,
    trial_name: str,
    overrides: Overrides | None = None,
    echo: Echo = _quiet,
    workers: int | None = None,
) -> Any:
    """``kisscal reconstruct``: 3D points of one trial, written to ``points3d.csv``."""
    from kisscal.grid import apply_linearisation
    from kisscal.io.cache import cache_key, is_current, mark_current
    from kisscal.io.files import write_json
    from kisscal.io.points3d import read_points3d, write_trial_points
    from kisscal.recon import reconstruct_trial

    config = _load(root)
    trial = config.trial(trial_name)
    params = stage_params(config, overrides)
    lins = _linearisations(root, config, echo)
    dlts = _read_dlts(root, config)
    path = out_dir(root) / "trials" / trial.name / "points3d.csv"
    stage_key = cache_key(
        "reconstruct",
        _trial_input_keys(config, trial),
        _linearisation_key(lins),
        dlts,
        params.detection,
        params.recon,
    )
    if is_current(path, stage_key):
        echo(f"  reconstruct {trial.name}: cached")
        return read_points3d(path)
    blobs = _trial_blobs(root, config, trial, params, echo, workers)
    fields, cams, uvs = [], [], []
    for ci, cam in enumerate(config.camera_ids):
        for f, xy in enumerate(blobs[cam]):
            fields.append(np.full(len(xy), f))
            cams.append(np.full(len(xy), ci))
            uvs.append(apply_linearisation(lins[cam], xy) if len(xy) else np.zeros((0, 2)))
    field_idx = np.concatenate(fields).astype(int)
    cam_idx = np.concatenate(cams).astype(int)
    uv = np.concatenate(uvs)
    order = np.lexsort((cam_idx, field_idx))
    field_idx, cam_idx, uv = field_idx[order], cam_idx[order], uv[order]
    t0 = time.perf_counter()
    points = reconstruct_trial(
        field_idx, cam_idx, uv, np.stack([dlts[c] for c in config.camera_ids]), params.recon
    )
    write_trial_points(path, points, field_idx, cam_idx, config.camera_ids)
    write_json(path.with_name("recon.json"), points.summary())
    mark_current(path, stage_key)
    if len(points) and trial.name == config.trials[0].name:  # one field is enough to see
        busiest = int(np.bincount(points.field).argmax())
        _figure(
            root,
            f"epipolar_{trial.name}",
            "kisscal.report.epipolar",
            "trial_field_figure",
            points,
            busiest,
            field_idx,
            cam_idx,
            uv,
            np.stack([dlts[c] for c in config.camera_ids]),
            [c.size_px for c in config.cameras],
            list(config.camera_ids),
        )
    n_fields = max(len(v) for v in blobs.values())
    echo(
        f"  reconstruct {trial.name}: {len(points)} points in {n_fields} fields, "
        f"median rms {np.median(points.rms_px) if len(points) else float('nan'):.3f} px "
        f"({time.perf_counter() - t0:.1f} s)"
    )
    return points


def _figure(root: Path, name: str, module: str, function: str, *args: Any) -> None:
    """Draw a stage figure into ``out/figures/<name>.png``.

    A figure that cannot be drawn (e.g. a degenerate trial) is skipped: figures
    illustrate the numbers, which are already written.
    """
    import importlib
    import warnings

    from kisscal.report.html import save_figure

    draw = getattr(importlib.import_module(module), function)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            save_figure(draw(*args), out_dir(root) / "figures" / f"{name}.png")
    except (ValueError, IndexError, KisscalError):
        return


# --------------------------------------------------------------------------- tracking


def track(
    root: Path,
    trial_name: str,
    overrides: Overrides | None = None,
    sweep: bool = False,
    echo: Echo = _quiet,
) -> Any:
    """``kisscal track``: labelled trajectories of a trial from its ``points3d.csv``.

    Writes ``trajectories.csv``, ``.c3d`` and ``.trc``; with ``sweep``, also the thesis'
    PNC x MNC segment-length table as ``sweep.csv``.
    """
    from kisscal.io.export import write_c3d, write_trc
    from kisscal.io.files import write_json
    from kisscal.io.points3d import read_points3d
    from kisscal.io.trajectories import write_trajectories_csv
    from kisscal.tracking import build_trajectories

    config = _load(root)
    trial = config.trial(trial_name)
    params = stage_params(config, overrides)
    tdir = out_dir(root) / "trials" / trial.name
    points_path = tdir / "points3d.csv"
    if not points_path.is_file():
        raise KisscalError(
            f"{points_path}: missing; run `kisscal reconstruct {root} {trial.name}` first"
        )
    pts = read_points3d(points_path)
    names = config.markers.names if config.markers else None
    template = config.markers.template_mm if config.markers else None
    t0 = time.perf_counter()
    segments = config.markers.segments if config.markers else ()
    result = build_trajectories(pts.field, pts.xyz_mm, params.tracking, names, template, segments)
    write_trajectories_csv(tdir / "trajectories.csv", result.tracks, result.labels)
    write_c3d(tdir / "trajectories.c3d", result.tracks, result.labels, config.rate_hz)
    write_trc(tdir / "trajectories.trc", result.tracks, result.labels, config.rate_hz)
    lab = result.labelling
    write_json(
        tdir / "tracking.json",
        {
            "pieces": result.n_pieces,
            "pieces_after_blending": result.n_pieces_blended,
            "trajectories": len(result.labels),
            "fits_marker_set": bool(lab.fits_marker_set),
            "unlabelled": list(lab.unlabelled),
            "missing": list(lab.missing),
            "predictions_per_track": dict(
                zip(result.labels, np.asarray(result.n_predicted).tolist(), strict=True)
            ),
        },
    )
    segments = config.markers.segments if config.markers else ()
    _figure(
        root, f"trajectories_{trial.name}", "kisscal.report.tracking", "trajectories_figure", result
    )
    _figure(
        root,
        f"segments_{trial.name}",
        "kisscal.report.tracking",
        "segment_length_figure",
        result,
        segments,
        config.rate_hz,
    )
    echo(
        f"  track {trial.name}: {len(result.labels)} trajectories from {result.n_pieces} pieces "
        f"({', '.join(result.labels[:20])}{' ...' if len(result.labels) > 20 else ''}) "
        f"({time.perf_counter() - t0:.1f} s)"
    )
    if sweep:
        from kisscal.io.trajectories import write_sweep_csv
        from kisscal.tracking import sweep_noise

        segments = config.markers.segments if config.markers else ()
        rows = sweep_noise(pts.field, pts.xyz_mm, segments, params.tracking, names, template)
        write_sweep_csv(tdir / "sweep.csv", rows)
        echo(f"  sweep: {tdir / 'sweep.csv'}")
    return result


# ------------------------------------------------------------------------- whole runs


def run(
    root: Path,
    overrides: Overrides | None = None,
    echo: Echo = _quiet,
    workers: int | None = None,
) -> dict[str, Any]:
    """``kisscal run``: linearise, calibrate, then reconstruct and track every trial.

    ``workers`` is the number of detection processes (default: one per core).

    Detection and calibration are cached: re-running after changing a tracking
    parameter redoes only tracking. Writes ``out/summary.json`` and returns it.
    """
    from kisscal.io.files import write_json

    root = Path(root)
    config = _load(root)
    stage_params(config, overrides)  # fail fast on bad parameters, before any work
    timings: dict[str, float] = {}
    t = time.perf_counter()
    echo("[1/4] linearisation")
    linearise(root, overrides=overrides, echo=echo)
    timings["linearise_s"] = time.perf_counter() - t
    t = time.perf_counter()
    echo("[2/4] calibration")
    calibrate(root, overrides=overrides, echo=echo, workers=workers)
    timings["calibrate_s"] = time.perf_counter() - t
    for trial in config.trials:
        t = time.perf_counter()
        echo(f"[3/4] reconstruction: {trial.name}")
        reconstruct(root, trial.name, overrides, echo, workers)
        timings[f"reconstruct_{trial.name}_s"] = time.perf_counter() - t
        t = time.perf_counter()
        echo(f"[4/4] tracking: {trial.name}")
        track(root, trial.name, overrides, echo=echo)
        timings[f"track_{trial.name}_s"] = time.perf_counter() - t
    summary = summarise(root)
    summary["timings"] = {k: round(v, 3) for k, v in timings.items()}
    write_json(out_dir(root) / "summary.json", summary)
    report(root, echo=echo)
    return summary


def summarise(root: Path) -> dict[str, Any]:
    """Every quality figure of a processed session, read back from ``out/``."""
    import json

    from kisscal.io.files import read_table

    config = _load(root)
    out = out_dir(root)
    cams: dict[str, Any] = {}
    for cam in config.camera_ids:
        entry: dict[str, Any] = {}
        lin_path = out / "linearisation" / f"{cam}.json"
        if lin_path.is_file():
            doc = json.loads(lin_path.read_text())
            entry["grid"] = {
                k: v for k, v in doc.items() if isinstance(v, (int, float)) and k != "scale_px"
            }
        dlt_path = out / "dlt" / f"{cam}.json"
        if dlt_path.is_file():
            doc = json.loads(dlt_path.read_text())
            entry["dlt"] = {
                "method": doc.get("method"),
                "rms_px": doc.get("rms_px"),
                "centre_mm": doc.get("centre_mm"),
            }
        cams[cam] = entry
    trials: dict[str, Any] = {}
    for trial in config.trials:
        tdir = out / "trials" / trial.name
        entry = {}
        if (tdir / "tracking.json").is_file():
            entry["tracking"] = json.loads((tdir / "tracking.json").read_text())
        if (tdir / "recon.json").is_file():
            entry["reconstruction"] = json.loads((tdir / "recon.json").read_text())
        if (tdir / "trajectories.csv").is_file():
            tr = read_table(tdir / "trajectories.csv")
            labels = sorted(set(tr["label"].tolist()))
            entry["trajectories"] = len(labels)
            entry["labels"] = labels
            status = tr["status"]
            entry["samples"] = {
                s: int(np.sum(status == s)) for s in ("measured", "predicted", "filled")
            }
        trials[trial.name] = entry
    check_path = out / "dlt" / "check.json"
    check = json.loads(check_path.read_text()) if check_path.is_file() else {}
    return {"session": config.name, "cameras": cams, "rods": check, "trials": trials}


# -------------------------------------------------------------------------------- check


@dataclass(frozen=True)
class CheckFailure:
    camera: str
    figure: str
    value: float
    limit: float


def check(
    root: Path,
    max_reproj_px: float | None = None,
    max_grid_px: float | None = None,
    max_3d_mm: float | None = None,
) -> list[CheckFailure]:
    """``kisscal check``: every figure over its limit (an empty list when all pass).

    Reads the outputs of ``kisscal linearise`` and ``kisscal calibrate``; no truth needed.
    """
    import json

    config = _load(root)
    out = out_dir(root)
    failures = []
    for cam in config.camera_ids:
        if max_grid_px is not None and config.grid is not None:
            path = out / "linearisation" / f"{cam}.json"
            if not path.is_file():
                raise KisscalError(f"{path}: missing; run `kisscal linearise {root}` first")
            value = float(json.loads(path.read_text())["rms_px"])
            if not value <= max_grid_px:
                failures.append(CheckFailure(cam, "grid rms_px", value, max_grid_px))
        if max_reproj_px is not None:
            path = out / "dlt" / f"{cam}.json"
            if not path.is_file():
                raise KisscalError(f"{path}: missing; run `kisscal calibrate {root}` first")
            value = float(json.loads(path.read_text())["rms_px"])
            if not value <= max_reproj_px:
                failures.append(CheckFailure(cam, "dlt rms_px", value, max_reproj_px))
    if max_3d_mm is not None:
        path = out / "dlt" / "check.json"
        if not path.is_file():
            raise KisscalError(f"{path}: missing; run `kisscal calibrate {root}` first")
        doc = json.loads(path.read_text())
        loo = doc.get("leave_one_rod_out", {})
        value = float(loo.get("mean_mm", doc.get("rods_in_sample_mean_mm", np.nan)))
        if not value <= max_3d_mm:
            failures.append(CheckFailure("all", "leave-one-rod-out mean mm", value, max_3d_mm))
    return failures


# ------------------------------------------------------------------------------ batch


def _run_quietly(root: str) -> dict[str, Any]:
    """One session of a batch, run in a Dask worker (single process: the batch is the
    parallelism); returns its summary, or ``{"error": message}`` for a user error."""
    try:
        return run(Path(root), workers=1)
    except KisscalError as exc:
        return {"error": str(exc)}


def batch(
    sessions: Sequence[Path], scheduler: str | None = None, echo: Echo = _quiet
) -> list[Path]:
    """``kisscal batch``: run many sessions in parallel on Dask; return the ones that failed.

    Without ``scheduler`` a local cluster (one single-threaded worker process per core)
    is started; with it, the sessions go to that Dask scheduler (a lab cluster), which
    must see the same paths. A session that fails is reported and does not stop the others.
    """
    import dask
    from dask.distributed import Client, LocalCluster

    paths = [Path(s).resolve() for s in sessions]
    if not paths:
        raise KisscalError("kisscal batch: give at least one session folder")
    # Worker processes must be able to start the detection's own process pool.
    with dask.config.set({"distributed.worker.daemon": False, "logging.distributed": "error"}):
        if scheduler:
            try:
                client = Client(scheduler, timeout="10s")
            except OSError as exc:
                raise KisscalError(f"cannot reach the Dask scheduler {scheduler}: {exc}") from None
            cluster = None
        else:
            n = max(1, min(len(paths), os.cpu_count() or 1))
            cluster = LocalCluster(
                n_workers=n, threads_per_worker=1, dashboard_address=None, silence_logs=40
            )
            client = Client(cluster)
        try:
            futures = client.map(_run_quietly, [str(p) for p in paths], pure=False)
            failed = []
            for path, future in zip(paths, futures, strict=True):
                try:
                    summary = future.result()
                    if "error" in summary:
                        raise KisscalError(summary["error"])
                    n_traj = sum(t.get("trajectories", 0) for t in summary["trials"].values())
                    echo(f"ok      {path}: {len(summary['trials'])} trials, {n_traj} trajectories")
                except Exception as exc:  # one failed session must not stop the others
                    failed.append(path)
                    echo(f"FAILED  {path}: {exc}")
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    echo(f"{len(paths) - len(failed)} of {len(paths)} sessions processed")
    return failed


# ------------------------------------------------------------------------------ synth


def default_walking5_path() -> Path | None:
    """The real walking trial shipped with kisscal (``kisscal/data/walking5.c3d``).

    ``KISSCAL_WALKING5`` names another copy; ``None`` when neither is a file.
    """
    env = os.environ.get("KISSCAL_WALKING5")
    candidates = [Path(env)] if env else []
    candidates.append(Path(__file__).resolve().parent / "data" / "walking5.c3d")
    return next((p for p in candidates if p.is_file()), None)


def synthesise(
    out: Path,
    *,
    seed: int = 1,
    fields: int = 200,
    n_cameras: int = 6,
    n_markers: int = 15,
    blur_px: float | None = None,
    walking5: bool = True,
    force: bool = False,
    n_jobs: int | None = None,
    echo: Echo = _quiet,
) -> Path:
    """Write a synthetic KISS-like session (images, ``session.toml``, ``truth/``) to ``out``.

    The same arguments give byte-identical files. With ``walking5`` the real Vicon trial
    is replayed through the synthetic cameras as trial ``walk5`` when it can be found.
    """
    from kisscal.io.synthetic import load_walking5, write_synthetic_session
    from kisscal.synth.plan import SynthOptions, plan_session
    from kisscal.synth.render import RenderParams

    if n_markers not in (13, 15):
        raise KisscalError(f"--markers must be 13 or 15, got {n_markers}")
    if not 2 <= n_cameras <= 6:
        raise KisscalError(f"--cameras must be between 2 and 6, got {n_cameras}")
    if fields < 10:
        raise KisscalError(f"--fields must be at least 10, got {fields}")
    render = RenderParams() if blur_px is None else RenderParams(blur_px=blur_px)
    options = SynthOptions(
        seed=seed, fields=fields, n_cameras=n_cameras, n_markers=n_markers, render=render
    )
    replay = None
    if walking5:
        path = default_walking5_path()
        if path is None:
            echo("walking5.c3d not found: the real-trial replay (walk5) is skipped")
        else:
            replay = load_walking5(path)
    plan = plan_session(options, replay)
    t0 = time.perf_counter()
    write_synthetic_session(
        Path(out), plan, f"synth-seed{seed}", force=force, n_jobs=n_jobs or os.cpu_count() or 1
    )
    echo(
        f"wrote {out}: {len(plan.rig)} cameras, grid and rod frames, trials "
        f"{', '.join(f'{t} ({m.n_fields} fields)' for t, m in plan.trials.items())}, "
        f"truth/ ({time.perf_counter() - t0:.1f} s)"
    )
    return Path(out)


def evaluate(root: Path) -> dict[str, Any]:
    """Score a processed synthetic session against its ``truth/`` (no truth: empty dict).

    Gait trials: trajectories vs true markers (labels, switches, RMSE, coverage); the
    stick trial: length error (seed 003, 5.1); the thrown marker: g from a parabola fit.
    """
    from kisscal.io.files import read_table
    from kisscal.synth.evaluate import (
        gravity_error,
        score_trajectories,
        stick_length_error,
        thrown_gravity,
    )

    config = _load(root)
    truth_dir = Path(root) / "truth" / "trials"
    result: dict[str, Any] = {}
    for trial in config.trials:
        traj_path = out_dir(root) / "trials" / trial.name / "trajectories.csv"
        truth_path = truth_dir / trial.name / "markers.csv"
        if not (traj_path.is_file() and truth_path.is_file()):
            continue
        tr = read_table(traj_path)
        truth = read_table(truth_path)
        field_t = tr["field"].astype(int)
        xyz = np.column_stack([tr["x_mm"], tr["y_mm"], tr["z_mm"]])
        vis = np.column_stack([truth[f"visible_{c}"] for c in config.camera_ids])
        score = score_trajectories(
            field_t,
            tr["label"],
            xyz,
            tr["status"],
            truth["field"].astype(int),
            truth["marker"],
            np.column_stack([truth["x_mm"], truth["y_mm"], truth["z_mm"]]),
            vis.sum(axis=1) >= 3,
        )
        entry: dict[str, Any] = dataclasses.asdict(score)
        if trial.name == "stick":
            mae, sd, n = stick_length_error(field_t, tr["label"], xyz, tr["status"])
            entry["stick_length"] = {"mean_abs_error_mm": mae, "sd_mm": sd, "samples": n}
        if trial.name == "throw":
            measured = tr["status"] == "measured"
            g = thrown_gravity(field_t[measured], xyz[measured], config.rate_hz)
            entry["gravity"] = {"g_m_s2": g, "relative_error": gravity_error(g)}
        result[trial.name] = entry
    return result


def demo(out: Path, *, seed: int = 1, echo: Echo = _quiet) -> dict[str, Any]:
    """``kisscal demo``: synthesise a KISS-like session into ``out``, run it, print figures.

    The printed figures are the ones written to ``out/out/summary.json`` (``truth`` holds
    the comparison with the synthetic ground truth).
    """
    from kisscal.io.files import write_json

    out = Path(out)
    t0 = time.perf_counter()
    if (out / "session.toml").is_file():
        echo(f"using the existing session in {out}")
    else:
        synthesise(out, seed=seed, echo=echo)
    summary = run(out, echo=echo)
    summary["truth"] = evaluate(out)
    summary["timings"]["total_s"] = round(time.perf_counter() - t0, 1)
    write_json(out_dir(out) / "summary.json", summary)
    try:
        report_path = report(out)
    except Exception as exc:  # the figures are a convenience; the numbers are already written
        echo(f"report not written: {exc}")
        report_path = None
    echo("")
    echo(f"kisscal demo: {summary['session']} ({summary['timings']['total_s']} s)")
    echo(f"{'camera':<8}{'grid rms px':>12}{'DLT rms px':>12}")
    for cam, entry in summary["cameras"].items():
        g = entry.get("grid", {}).get("rms_px", float("nan"))
        d = entry.get("dlt", {}).get("rms_px", float("nan"))
        echo(f"{cam:<8}{g:>12.3f}{d:>12.3f}")
    rods = summary.get("rods", {})
    if rods:
        loo = rods.get("leave_one_rod_out", {}).get("mean_mm", float("nan"))
        in_sample = rods.get("rods_in_sample_mean_mm", float("nan"))
        echo(f"rod markers, 3D error in-sample {in_sample:.3f} mm, leave-one-rod-out {loo:.3f} mm")
    for trial, t in summary["truth"].items():
        line = (
            f"{trial}: {t['n_trajectories']} trajectories for {t['n_true_markers']} markers, "
            f"{t['correctly_labelled']} labelled right, 3D RMSE {t['rmse_measured_mm']:.2f} mm "
            f"(filled {t['rmse_filled_mm']:.2f} mm), coverage {100 * t['coverage']:.1f} %"
        )
        if "stick_length" in t:
            sl = t["stick_length"]
            line += f"; stick length error {sl['mean_abs_error_mm']:.2f} +/- {sl['sd_mm']:.2f} mm"
        if "gravity" in t:
            line += f"; g = {t['gravity']['g_m_s2']:.3f} m/s^2"
        echo(line)
    echo(f"summary: {out_dir(out) / 'summary.json'}")
    if report_path is not None:
        echo(f"report:  {report_path}")
    return summary


def report(root: Path, echo: Echo = _quiet) -> Path:
    """``kisscal report``: rebuild ``out/report.html`` from the session's outputs."""
    from kisscal.report.html import build_report

    _load(root)  # a session folder, not just any path
    path = build_report(Path(root))
    echo(f"report: {path}")
    return path
