"""Everything the report shows, read once from a processed session's ``out/`` folder.

Every input but ``summary.json`` is optional: a section whose file is absent is simply
not shown, so outputs of later stages (detection settings, wand, gait events) slot in
when they appear. A file that cannot be read is skipped with a note, never an error:
the report must be written even for a half-processed session.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.errors import KisscalError
from kisscal.io.calibration_record import LensModels, TargetRecord, WandRecord
from kisscal.io.config import load_session
from kisscal.io.detection_record import DetectionRecord
from kisscal.io.dltfiles import DltFile
from kisscal.io.files import read_table
from kisscal.io.store import SessionStore
from kisscal.io.summary import CameraFigures, RigCheck, TrialFigures, summarise
from kisscal.markersets import marker_set
from kisscal.report.markers import Dense, dense_trajectories
from kisscal.report.params import ReportParams
from kisscal.tracking.tracks import STATUS_NAMES

#: ``out/limits.json`` keys: the ``kisscal check`` options, named as in :class:`ReportParams`.
LIMIT_KEYS = ("max_grid_px", "max_reproj_px", "max_3d_mm")


@dataclass(frozen=True)
class TrialOutputs:
    """One trial's files: trajectories, and gait tables when the gait stage wrote them."""

    name: str
    dense: Dense | None = None
    events: dict[str, Any] | None = None
    spatiotemporal: dict[str, Any] | None = None


@dataclass(frozen=True)
class SessionOutputs:
    """What :func:`gather` read from ``out/``.

    Attributes
    ----------
    session : str
        Session name.
    rate_hz : float
        Field rate (1.0 when unknown: times are then in fields).
    cameras, trials : tuple of str
        In ``session.toml`` order (else in ``summary.json`` order).
    marker_names : tuple of str
        The session's marker set (empty without ``[markers]``).
    segments : tuple of (str, str)
        The marker set's rigid segments.
    summary : dict
        ``out/summary.json``.
    dlt : dict
        Camera -> its calibration (``out/dlt/<camera>.json``).
    detection : dict
        Camera -> its detection settings (``out/detection/<camera>.json``).
    wand : WandRecord or None
        ``out/dlt/wand.json``.
    trial_outputs : dict
        Trial -> :class:`TrialOutputs`.
    figures : dict
        Figure name -> PNG path in ``out/figures/``.
    limits : ReportParams
        Limits of the status block.
    notes : list of str
        Files that could not be read.
    """

    root: Path
    session: str
    rate_hz: float
    cameras: tuple[str, ...]
    trials: tuple[str, ...]
    marker_names: tuple[str, ...]
    segments: tuple[tuple[str, str], ...]
    summary: dict[str, Any]
    dlt: dict[str, DltFile]
    detection: dict[str, DetectionRecord]
    wand: WandRecord | None
    trial_outputs: dict[str, TrialOutputs]
    figures: dict[str, Path]
    limits: ReportParams
    notes: list[str] = field(default_factory=list)

    def camera_figures(self, camera: str) -> CameraFigures:
        """The figures of ``camera`` in :attr:`summary`, typed."""
        return CameraFigures.read(self.summary, camera)

    def lens_models(self, camera: str) -> LensModels | None:
        """The camera models compared for ``camera`` (None when its calibration has none)."""
        return LensModels.read(self.dlt[camera].data) if camera in self.dlt else None

    def rig_check(self) -> RigCheck:
        """The calibration's 3D check in :attr:`summary`, typed."""
        return RigCheck.read(self.summary)

    def target(self) -> TargetRecord | None:
        """The known target's match per camera in :attr:`summary` (None without one)."""
        return TargetRecord.read(self.summary.get("target"))

    def trial_figures(self, trial: str) -> TrialFigures:
        """The figures of ``trial`` in :attr:`summary`, typed."""
        return TrialFigures.read(self.summary, trial)


def _noted(
    notes: list[str], read: Callable[..., Any], *args: Any, note: str = "{}", **kwargs: Any
) -> Any:
    """``read(*args, **kwargs)``, or None with a note (``note`` around the error) when the
    file cannot be read."""
    try:
        return read(*args, **kwargs)
    except (KisscalError, OSError) as exc:
        notes.append(note.format(exc))
        return None


def _table(path: Path, notes: list[str]) -> Any:
    return _noted(notes, read_table, path, numeric=()) if path.is_file() else None


def _trial(store: SessionStore, name: str, notes: list[str]) -> TrialOutputs:
    files = store.trial(name)
    t = _noted(notes, store.trajectories, name) if files.trajectories().is_file() else None
    dense = None
    if t is not None:
        status = np.asarray(STATUS_NAMES)[t.status]
        dense = dense_trajectories(t.field, t.track, t.label, t.xyz_mm, status)
    return TrialOutputs(
        name, dense, _table(files.events, notes), _table(files.spatiotemporal, notes)
    )


def _limits(store: SessionStore, base: ReportParams, notes: list[str]) -> ReportParams:
    """``kisscal check`` limits stored in ``out/limits.json`` replace the defaults."""
    stored = _noted(notes, store.read_json, store.limits_path) or {}
    changes = {k: v for k, v in stored.items() if k in LIMIT_KEYS and v is not None}
    try:
        return base.replace(**changes)
    except KisscalError as exc:
        notes.append(f"limits.json ignored: {exc}")
        return base


def _marker_names(config: Any, notes: list[str]) -> tuple[tuple, tuple]:
    """The session's marker names and segments: ``[markers]`` names, or its set's."""
    markers = config.markers
    if markers is None:
        return (), ()
    own = tuple(markers.names), tuple(markers.segments)
    if markers.set is None:
        return own
    chosen = _noted(notes, marker_set, markers.set, markers.names or None)
    return own if chosen is None else (chosen.names, own[1] or chosen.segments)


def _session_params(config: Any, notes: list[str]) -> ReportParams:
    """The session's ``[report]`` table (the defaults where it has none, or is invalid)."""
    if config is None:
        return ReportParams()
    try:
        return ReportParams.from_layers(config.sections.get("report", {}))
    except KisscalError as exc:
        notes.append(f"[report] not used: {exc}")
        return ReportParams()


def gather(root: Path, params: ReportParams | None = None) -> SessionOutputs:
    """Read a processed session's outputs for :func:`kisscal.report.html.build_report`."""
    root = Path(root)
    store = SessionStore(root)
    notes: list[str] = []
    note = "session.toml not read ({}); names come from summary.json"
    config = _noted(notes, load_session, root, note=note)
    summary = _noted(notes, store.read_json, store.summary_path)
    if summary is None and config is not None:  # a stage run on its own: read from out/
        note = "summary.json missing and outputs not read ({})"
        summary = _noted(notes, summarise, root, note=note)
    summary = summary or {}
    if config is not None:
        cameras, trials = config.camera_ids, tuple(t.name for t in config.trials)
        names, segments = _marker_names(config, notes)
        rate_hz, session = float(config.rate_hz), config.name
    else:
        cameras = tuple(summary.get("cameras", {}))
        trials = tuple(summary.get("trials", {}))
        names, segments, rate_hz = (), (), 1.0
        session = str(summary.get("session", root.name))
    figures_dir = store.figures_dir
    # a hidden name is a figure still being written (kisscal.io.files writes beside, then renames)
    pngs = sorted(figures_dir.glob("[!.]*.png")) if figures_dir.is_dir() else []
    figures = {p.stem: p for p in pngs}
    detection = {c: r for c in cameras if (r := _noted(notes, store.detection_record, c))}
    return SessionOutputs(
        root=root,
        session=session,
        rate_hz=rate_hz,
        cameras=cameras,
        trials=trials,
        marker_names=names,
        segments=segments,
        summary=summary,
        dlt={
            c: d
            for c in cameras
            if store.dlt_path(c).is_file() and (d := _noted(notes, store.dlt, c))
        },
        detection=detection,
        wand=WandRecord.read(_noted(notes, store.calibration_doc, "wand")),
        trial_outputs={t: _trial(store, t, notes) for t in trials},
        figures=figures,
        limits=_limits(store, params or _session_params(config, notes), notes),
        notes=notes,
    )
