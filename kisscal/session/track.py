"""``kisscal track``: a trial's 3D points to labelled trajectories, their exports and gait."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

import numpy as np

from kisscal._text import plural
from kisscal.dlt.model import pixel_size_mm
from kisscal.errors import KisscalError
from kisscal.io.config import SessionConfig
from kisscal.io.export import write_c3d, write_sample_cameras, write_trc
from kisscal.io.files import read_json, write_json
from kisscal.io.points3d import Points3DFile
from kisscal.io.store import SessionStore
from kisscal.io.trajectories import write_sweep_csv, write_trajectories_csv
from kisscal.report.markers import dense_trajectories
from kisscal.report.params import ReportParams
from kisscal.report.tracking import segment_length_figure, trajectories_figure
from kisscal.report.validation import rate_doubt, throw_fit
from kisscal.session.calibrated import current_rig
from kisscal.session.gait import clear_gait_outputs, gait_outputs
from kisscal.session.inputs import figure, writes_session
from kisscal.session.markers import (
    MarkerSpec,
    marker_spec,
    static_inputs,
    subject_template,
)
from kisscal.session.params import Overrides, StageParams, stage_params
from kisscal.session.progress import Echo, quiet
from kisscal.tracking import (
    STATUS_NAMES,
    SpareBlobs,
    Trajectories,
    build_trajectories,
    spare_blobs,
    sweep_noise,
)
from kisscal.tracking.params import reconstructed_points


@writes_session
def track(
    root: Path,
    trial_name: str,
    overrides: Overrides | None = None,
    sweep: bool = False,
    echo: Echo = quiet,
    *,
    config: SessionConfig,
) -> Trajectories:
    """``kisscal track``: labelled trajectories of a trial from its ``points3d.csv``.

    Writes ``trajectories.csv``, ``.c3d`` and ``.trc`` and ``tracking.json``; when the
    labels carry the marker set's feet, also ``events.csv``, ``spatiotemporal.csv`` and
    ``gait.json`` (and the events into the C3D); with ``sweep``, the thesis' PNC x MNC
    segment-length table as ``sweep.csv``. With ``[markers] static``, the static trial is
    labelled first (or read from its cache) and its positions are the template.
    ``config`` is the session's, read from ``root`` when the caller has none
    (:func:`~kisscal.session.inputs.loads_config`).
    """
    root = Path(root)
    trial = config.trial(trial_name)
    params = stage_params(config, overrides)
    spec = marker_spec(config)
    static = config.markers.static if config.markers else None
    if static is not None and trial.name != static:
        spec = _with_static(root, config, spec, params, echo)
    result = _track_trial(root, config, trial.name, spec, params, echo)
    if sweep:
        store = SessionStore(root)
        files = store.trial(trial.name)
        pts = store.points3d(trial.name)
        rows = sweep_noise(
            pts.field, pts.xyz_mm, spec.segments, params.tracking, spec.names, spec.template_mm
        )
        write_sweep_csv(files.sweep, rows)
        echo(f"  sweep: {files.sweep}")
    return result


def _track_trial(
    root: Path, config: SessionConfig, trial: str, spec: MarkerSpec, params: StageParams, echo: Echo
) -> Trajectories:
    """Track and label one trial and write its outputs: gait ones, or, for the static
    trial, the subject's template (checked before anything is written)."""
    store = SessionStore(root)
    files = store.trial(trial)
    points_path = store.reconstructed(trial)
    pts = store.points3d(trial)
    from_c3d = config.trial(trial).source == "c3d"
    tracking = reconstructed_points(params.tracking) if from_c3d else params.tracking
    t0 = time.perf_counter()
    result = build_trajectories(
        pts.field,
        pts.xyz_mm,
        tracking,
        spec.names,
        spec.template_mm,
        spec.segments,
        marker_set=spec.marker_set if spec.label_with_set else None,
        rate_hz=config.rate_hz,
        template_upright=spec.template_upright,
        spare=None if from_c3d else _spare_blobs(config, trial),
    )
    static = config.markers.static if config.markers else None
    template = subject_template(result, spec, trial) if trial == static else None
    # every field of the trial (recon.json's count: blank fields count), trailing ones
    # without points too (a trial without markers still gets its files: header only)
    recon = read_json(files.recon) or {}
    frames = max(int(recon.get("fields", 0)), int(pts.field.max(initial=-1)) + 1, 1)
    write_trajectories_csv(files.trajectories(), result.tracks, result.labels)
    write_trc(
        files.trajectories(".trc"),
        result.tracks,
        result.labels,
        config.rate_hz,
        up=config.export.trc_up,
        n_fields=frames,
    )
    events = None
    if template is not None:
        clear_gait_outputs(root, trial)
        write_json(files.template, template)
        key = store.key(*static_inputs(points_path, spec, params.tracking))
        store.mark_current(files.template, key)
    else:
        events = gait_outputs(
            root, trial, result, spec.marker_set, config.rate_hz, params.gait, echo
        )
    write_c3d(
        files.trajectories(".c3d"),
        result.tracks,
        result.labels,
        config.rate_hz,
        points=pts,
        residual_mm=None if from_c3d else _residual_mm(config, pts),
        events=events,
        n_fields=frames,
        first_frame=int(recon.get("first_frame", 1)),  # a C3D trial's, else 1
    )
    if len(pts.camera_ids):
        write_sample_cameras(files.trajectory_cameras, result.tracks, result.labels, pts)
    write_json(files.tracking, _tracking_summary(result))
    title = f"trial {trial}: trajectories (mm)"
    figure(root, f"trajectories_{trial}", trajectories_figure, result, title)
    figure(root, f"segments_{trial}", segment_length_figure, result, spec.segments, config.rate_hz)
    shown = ", ".join(result.labels[:20]) + (" ..." if len(result.labels) > 20 else "")
    echo(
        f"  track {trial}: {plural(len(result.labels), 'trajectory')} from "
        f"{plural(result.n_pieces, 'piece')} ({shown}) ({time.perf_counter() - t0:.1f} s)"
    )
    doubt = _rate_doubt(config, trial, result, params.report)
    if doubt:
        echo(f"  warning: {trial}: {doubt}")
    lab = result.labelling
    if lab.flagged:
        echo(f"  track {trial}: uncertain labels, check them: {', '.join(lab.flagged)}")
    if events is not None:
        echo(f"  gait {trial}: {len(events)} events (events.csv, spatiotemporal.csv)")
    if not len(result.tracks.field):
        echo(f"  warning: {trial}: no trajectories; empty files written ({frames} fields)")
    return result


def _spare_blobs(config: SessionConfig, trial: str) -> SpareBlobs | None:
    """The trial's 2D blobs (``points2d.csv``), linearised, with the rig's cameras and
    the 3D point each went into: for single-camera fill (those of points no named
    track holds are freed). None without the file or a calibrated rig."""
    store = SessionStore(config.root)
    if not store.trial(trial).points2d.is_file():
        return None
    try:
        rig = current_rig(config.root, config=config)
        obs = store.points2d(trial)
    except KisscalError:
        return None
    ours = np.isin(obs.camera, rig.ids)
    cam = np.array([rig.index(c) for c in obs.camera[ours]], dtype=np.int64)
    uv = np.zeros((cam.size, 2))
    for i, camera in enumerate(rig):
        uv[cam == i] = camera.undistort_px(obs.xy_px[ours][cam == i])
    return spare_blobs(obs.field[ours], cam, uv, rig.dlts, obs.point[ours])


def _residual_mm(config: SessionConfig, pts: Points3DFile) -> np.ndarray | None:
    """Each point's reconstruction residual in mm: ``rms_px`` times the mean size of a pixel
    at the point over the cameras that saw it (None without a calibrated rig)."""
    if not len(pts.field):
        return None
    try:
        rig = current_rig(config.root, config=config)
    except KisscalError:
        return None
    index = [rig.index(c) for c in pts.camera_ids]
    row, col = np.nonzero(pts.blob >= 0)
    size = pixel_size_mm(rig.dlts, np.asarray(index)[col], pts.xyz_mm[row])
    mean = np.bincount(row, size, len(pts.field)) / np.maximum(
        np.bincount(row, minlength=len(pts.field)), 1
    )
    return np.where(mean > 0, pts.rms_px * mean, np.nan)


def _rate_doubt(
    config: SessionConfig, trial: str, result: Trajectories, limits: ReportParams
) -> str:
    """Why ``rate_hz`` may be wrong, when the trial is a throw that does not fall at g."""
    tracks = result.tracks
    if not len(tracks.field) or result.labelling.fits_marker_set:
        return ""
    status = np.asarray(STATUS_NAMES, dtype=object)[tracks.status]
    labels = np.asarray(result.labels, dtype=object)[tracks.track]
    dense = dense_trajectories(tracks.field, tracks.track, labels, tracks.xyz_mm, status)
    fit = throw_fit(dense, trial, config.rate_hz, limits.g_m_s2)
    return "" if fit is None else rate_doubt(fit, config.rate_hz, limits.g_m_s2, limits.max_g_error)


def _with_static(
    root: Path, config: SessionConfig, spec: MarkerSpec, params: StageParams, echo: Echo
) -> MarkerSpec:
    """``spec`` with the static trial's template (labelling the static trial first unless
    its template is current)."""
    static = config.markers.static if config.markers else ""
    store = SessionStore(root)
    path = store.trial(static).template
    key = store.key(*static_inputs(store.reconstructed(static), spec, params.tracking))
    if store.is_current(path, key):
        echo(f"  static trial {static}: template from its outputs (cached)")
    else:
        echo(f"  static trial {static}: labelled first; its positions are the template")
        _track_trial(root, config, static, spec, params, echo)
    doc = read_json(path)
    return dataclasses.replace(
        spec,
        names=tuple(doc["names"]),
        template_mm=np.asarray(doc["template_mm"], dtype=float),
        template_upright=True,
    )


def _tracking_summary(result: Trajectories) -> dict[str, Any]:
    lab = result.labelling
    return {
        "pieces": result.n_pieces,
        "pieces_after_blending": result.n_pieces_blended,
        "trajectories": len(result.labels),
        "fits_marker_set": bool(lab.fits_marker_set),
        "unlabelled": list(lab.unlabelled),
        "missing": list(lab.missing),
        "labels_certain": bool(lab.fits_marker_set and lab.certain),
        "flagged": list(lab.flagged),
        "confidence": {k: round(v, 3) for k, v in lab.confidence.items()},
        "exchanged": [list(p) for p in lab.exchanged],
        "sides_from": lab.sides_from,
        "mirror_fit_ratio": _finite(lab.mirror_fit_ratio),
        "height_mm": _finite(lab.height_mm),
        "fit_rms_mm": _finite(lab.fit_rms_mm),
        "predictions_per_track": dict(
            zip(result.labels, np.asarray(result.n_predicted).tolist(), strict=True)
        ),
        "fills": [
            {
                "label": result.labels[g.track],
                "first_field": g.first_field,
                "fields": g.n_fields,
                "method": STATUS_NAMES[g.status].removeprefix("filled_"),
                "expected_error_mm": _finite(g.expected_error_mm),
                "from": [result.labels[d] for d in g.donors],
                "single_camera_fields": g.ray_fields,
            }
            for g in result.fills
        ],
    }


def _finite(x: float) -> float | None:
    return round(float(x), 3) if np.isfinite(x) else None
