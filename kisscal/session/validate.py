"""``kisscal validate``: every missing or inconsistent input of a session, before any work.

A session is hours of a patient's time; a frame missing in one camera of the last trial
must not be found after linearisation and calibration ran. :func:`validate` opens every
input the session names (one frame per image set, every centroid file header, every
video's frame count) and lists each problem at once, tagged with what it stops: the
calibration (nothing can run) or one trial (the others still can).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from kisscal.errors import KisscalError
from kisscal.io.config import SessionConfig, TrialConfig
from kisscal.io.dltfiles import read_control_points_csv
from kisscal.io.files import read_table
from kisscal.io.frames import camera_frames
from kisscal.report.params import ReportParams
from kisscal.session.inputs import image_sources, load_config, needs_calibration
from kisscal.session.params import Overrides, stage_params
from kisscal.session.reconstruct import CENTROID_COLUMNS
from kisscal.target.match import too_few_seeds

#: ``Problem.scope`` of a problem that stops the whole session.
SESSION = "session"


@dataclass(frozen=True)
class Problem:
    """One thing wrong with a session's inputs.

    ``scope`` is :data:`SESSION` when nothing can be processed (calibration inputs,
    parameters) or the name of the one trial it stops.
    """

    scope: str
    message: str

    def __str__(self) -> str:
        where = "" if self.scope == SESSION else f"trial {self.scope}: "
        return where + self.message


def validate(root: Path, overrides: Overrides | None = None) -> list[Problem]:
    """Every problem with the inputs of the session at ``root`` (empty: ready to run).

    Raises :class:`KisscalError` only when ``session.toml`` itself cannot be read, since
    then nothing else can be checked.
    """
    config = load_config(root)
    problems = _parameters(config, overrides)
    problems += _calibration_inputs(config)
    for trial in config.trials:
        problems += [Problem(trial.name, m) for m in _trial_inputs(config, trial)]
    return problems


def _parameters(config: SessionConfig, overrides: Overrides | None) -> list[Problem]:
    try:
        stage_params(config, overrides)
        ReportParams.from_layers(config.sections.get("report", {}))
    except KisscalError as exc:
        return [Problem(SESSION, str(exc))]
    return []


def _calibration_inputs(config: SessionConfig) -> list[Problem]:
    problems = []
    if (
        config.rods is None
        and config.calibration is None
        and config.wand is None
        and needs_calibration(config)
    ):
        problems.append(
            Problem(SESSION, "no [rods], [calibration] or [wand]: nothing to calibrate from")
        )
    for what, pattern, video, fields in image_sources(config):
        if what.startswith("trial"):
            continue
        problems += [Problem(SESSION, m) for m in _frame_set(config, what, pattern, video, fields)]
    return problems + [Problem(SESSION, m) for m in _calibration_files(config)]


def _calibration_files(config: SessionConfig) -> list[str]:
    """Files a ``[calibration]`` names: one per session, or one per camera."""
    calibration = config.calibration
    if calibration is None:
        return []
    missing = []
    for key in ("cameras", "dlt", "target"):
        name = getattr(calibration, key)
        if name and not (config.root / name).is_file():
            missing.append(f"{config.root / name}: calibration.{key} not found")
    for key in ("points", "seeds"):
        pattern = getattr(calibration, key)
        for cam in config.camera_ids if pattern else ():
            path = config.root / pattern.replace("{camera}", cam)
            if not path.is_file():
                missing.append(f"{path}: calibration {key} of camera {cam} not found")
            elif key == "seeds":
                missing += _seed_problems(path, cam)
    return missing


def _seed_problems(path: Path, camera: str) -> list[str]:
    """A camera's seeds file: readable, and as many seeds as ``calibrate`` needs."""
    try:
        uv, _, _ = read_control_points_csv(path)
    except KisscalError as exc:
        return [str(exc)]
    few = too_few_seeds(len(uv))
    return [f"{path}: camera {camera}: {few}"] if few else []


def _frame_set(
    config: SessionConfig, what: str, pattern: str, video: bool, fields: str | None = None
) -> list[str]:
    """Problems of one set of frames: missing per camera, or of another size."""
    return _frames_and_counts(config, what, pattern, video, fields)[0]


def _frames_and_counts(
    config: SessionConfig, what: str, pattern: str, video: bool, fields: str | None = None
) -> tuple[list[str], dict[str, int]]:
    problems, counts = [], {}
    for cam in config.cameras:
        try:
            frames = camera_frames(config.root, pattern, cam.id, what, video, fields)
            counts[cam.id] = len(frames)
            size = _frame_size(frames[0]) if len(frames) else None
        except KisscalError as exc:
            problems.append(str(exc))
            continue
        if size is None:
            problems.append(f"{pattern}: no {what} frames for camera {cam.id}")
        elif cam.size_px is not None and size != cam.size_px:
            problems.append(
                f"camera {cam.id}: {what} frames are {size[0]} x {size[1]} pixels, "
                f"[[cameras]] size says {cam.size_px[0]} x {cam.size_px[1]}"
            )
    return problems, counts


def _frame_size(frame: object) -> tuple[int, int]:
    h, w = frame.shape[:2]  # type: ignore[attr-defined]
    return int(w), int(h)


def _trial_inputs(config: SessionConfig, trial: TrialConfig) -> list[str]:
    if trial.source == "centroids":
        return _centroid_inputs(config, trial)
    if trial.source == "c3d":
        path = config.root / (trial.c3d or "")
        return [] if path.is_file() else [f"{path}: C3D file not found"]
    pattern = trial.images or trial.video or ""
    problems, counts = _frames_and_counts(
        config, "trial", pattern, trial.source == "video", trial.fields
    )
    if not problems and len(set(counts.values())) > 1:
        detail = ", ".join(f"{c}: {n}" for c, n in counts.items())
        problems.append(f"cameras have different numbers of frames ({detail})")
    return problems


def _centroid_inputs(config: SessionConfig, trial: TrialConfig) -> list[str]:
    problems = []
    for cam in config.camera_ids:
        path = config.root / (trial.centroids or "").replace("{camera}", cam)
        try:
            read_table(path, required=CENTROID_COLUMNS, numeric=CENTROID_COLUMNS)
        except KisscalError as exc:
            problems.append(str(exc))
    return problems
