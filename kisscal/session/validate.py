"""``kisscal validate``: every missing or inconsistent input of a session, before any work.

A session is hours of a patient's time; a frame missing in one camera of the last trial
must not be found after linearisation and calibration ran. :func:`validate` opens every
input the session names (every image file's header, not its pixels; every centroid file
header; every video's frame count and first frame; every C3D trial's rate) and lists each
problem at once, tagged with what it stops: the calibration (nothing can run) or one
trial (the others still can). Warnings (JPEG data in a lossless file name) stop nothing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from kisscal.errors import KisscalError
from kisscal.io.c3d import no_points, read_c3d_points
from kisscal.io.config import SessionConfig, TrialConfig
from kisscal.io.dltfiles import read_control_points_csv
from kisscal.io.files import read_table
from kisscal.io.frames import (
    LOSSY_FORMATS,
    camera_frames,
    image_header,
    source_files,
)
from kisscal.session.inputs import folders_hint, image_sources, loads_config, needs_calibration
from kisscal.session.params import Overrides, stage_params
from kisscal.session.trials import CENTROID_COLUMNS
from kisscal.target.seeds import clicked, too_few_seeds

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
    #: A doubt about the input, not an error: it stops nothing.
    warning: bool = False

    def __str__(self) -> str:
        where = "" if self.scope == SESSION else f"trial {self.scope}: "
        return where + self.message


@loads_config
def validate(
    root: Path, overrides: Overrides | None = None, *, config: SessionConfig
) -> list[Problem]:
    """Every problem with the inputs of the session at ``root`` (empty: ready to run).

    Raises :class:`KisscalError` only when ``session.toml`` itself cannot be read, since
    then nothing else can be checked. ``config`` is the session's, read from ``root`` when
    the caller has none.
    """
    problems = _parameters(config, overrides)
    problems += _calibration_inputs(config)
    for trial in config.trials:
        problems += [_problem(trial.name, m) for m in _trial_inputs(config, trial)]
    return list(dict.fromkeys(problems))  # misnamed camera folders show in every frame set


def _problem(scope: str, message: str) -> Problem:
    """A problem, or a warning when the message says it is one (``warning: ...``)."""
    if message.startswith(_WARNING):
        return Problem(scope, message.removeprefix(_WARNING), warning=True)
    return Problem(scope, message)


_WARNING = "warning: "


def _parameters(config: SessionConfig, overrides: Overrides | None) -> list[Problem]:
    try:
        stage_params(config, overrides)
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
        found = _frames_and_counts(config, what, pattern, video, fields)[0]
        problems += [_problem(SESSION, m) for m in found]
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
        for cam in config.cameras if pattern else ():
            path = config.root / pattern.replace("{camera}", cam.id)
            if not path.is_file():
                missing.append(f"{path}: calibration {key} of camera {cam.id} not found")
            elif key == "seeds":
                missing += _seed_problems(path, cam.id, cam.size_px)
    return missing


def _seed_problems(path: Path, camera: str, size_px: tuple[int, int] | None) -> list[str]:
    """A camera's seeds file: readable, and as many seeds on the image (clicks: where its
    size is not given, not left of or above it) as ``calibrate`` needs."""
    try:
        uv, _, _ = read_control_points_csv(path)
    except KisscalError as exc:
        return [str(exc)]
    few = too_few_seeds(int(clicked(uv, size_px).sum()))
    return [f"{path}: camera {camera}: {few}"] if few else []


def _frames_and_counts(
    config: SessionConfig, what: str, pattern: str, video: bool, fields: str | None = None
) -> tuple[list[str], dict[str, int]]:
    """Problems of one set of frames (missing per camera, or of another size), and the
    number of frames of each camera."""
    problems, counts, missing = [], {}, []
    for cam in config.cameras:
        try:
            frames = camera_frames(config.root, pattern, cam.id, what, video, fields)
        except KisscalError as exc:
            missing.append(str(exc))
            continue
        counts[cam.id] = len(frames)
        try:
            problems += _frame_sizes(cam.id, cam.size_px, what, frames)
        except KisscalError as exc:
            problems.append(str(exc))
    hint = folders_hint(config, pattern) if missing else ""
    return ([hint] if hint else missing) + problems, counts


def _frame_sizes(
    camera: str, size: tuple[int, int] | None, what: str, frames: Sequence
) -> list[str]:
    """Problems of a camera's frame sizes: each frame's size from its file header
    (a video: its first frame) against ``[[cameras]] size``, or against the first frame."""
    if not len(frames):
        return [f"no {what} frames for camera {camera}"]
    paths = source_files(frames)
    if getattr(frames, "sequential", False):  # a video: every frame has the first's size
        h, w = frames[0].shape[:2]
        sizes, problems = [(int(w), int(h))], []
    else:
        headers = [image_header(p) for p in paths]
        order = getattr(frames, "order", None)
        sizes = [_field_size(h.size, order) for h in headers]
        problems = _lossy(camera, what, paths, [h.format for h in headers])
    expected = size if size is not None else sizes[0]
    given = "[[cameras]] size says" if size is not None else "its first frame is"
    odd = [i for i, s in enumerate(sizes) if s != expected]
    if odd:
        name, (w, h) = paths[odd[0]], sizes[odd[0]]
        more = f" (and {len(odd) - 1} more)" if len(odd) > 1 else ""
        problems.append(
            f"camera {camera}: {what} frame {name} is {w} x {h} pixels{more}, "
            f"{given} {expected[0]} x {expected[1]}"
        )
    return problems


def _field_size(size: tuple[int, int], order: str | None) -> tuple[int, int]:
    """The size of a frame's first field (``order`` None: the frame is not split)."""
    w, h = size
    if order is None:
        return w, h
    first = 0 if order == "top-first" else 1
    return w, len(range(first, h, 2))


def _lossy(camera: str, what: str, paths: list[Path], formats: list[str]) -> list[str]:
    """A warning when files named as lossless images hold JPEG data."""
    jpeg = [p for p, f in zip(paths, formats, strict=True) if f in LOSSY_FORMATS]
    jpeg = [p for p in jpeg if p.suffix.lower() not in (".jpg", ".jpeg")]
    if not jpeg:
        return []
    return [
        f"{_WARNING}camera {camera}: {len(jpeg)} of {len(paths)} {what} frames "
        f"({jpeg[0].name}, ...) hold JPEG data under a {jpeg[0].suffix or 'suffix-less'} "
        "name: lossy compression moves marker centroids; export the frames losslessly"
    ]


def _trial_inputs(config: SessionConfig, trial: TrialConfig) -> list[str]:
    if trial.source == "centroids":
        return _centroid_inputs(config, trial)
    if trial.source == "c3d":
        return _c3d_input(config, trial)
    pattern = trial.images or trial.video or ""
    problems, counts = _frames_and_counts(
        config, "trial", pattern, trial.source == "video", trial.fields
    )
    if not problems and len(set(counts.values())) > 1:
        detail = ", ".join(f"{c}: {n}" for c, n in counts.items())
        problems.append(f"cameras have different numbers of frames ({detail})")
    return problems


def _c3d_input(config: SessionConfig, trial: TrialConfig) -> list[str]:
    """A C3D trial's file is there and recorded at the session's ``rate_hz``."""
    path = config.root / (trial.c3d or "")
    if not path.is_file():
        return [f"{path}: C3D file not found"]
    try:
        _, xyz, rate = read_c3d_points(path)
    except KisscalError as exc:
        return [str(exc)]
    if not xyz.shape[1]:  # before the rate: such files often give a point rate of 0
        return [f"{path}: {no_points(xyz)}"]
    if abs(rate - config.rate_hz) > 1e-6 * rate:
        return [
            f"{path}: recorded at {rate:g} frames per second, but [session] rate_hz = "
            f"{config.rate_hz:g}: is rate_hz right?"
        ]
    return []


def _centroid_inputs(config: SessionConfig, trial: TrialConfig) -> list[str]:
    problems = []
    for cam in config.camera_ids:
        path = config.root / (trial.centroids or "").replace("{camera}", cam)
        try:
            read_table(path, required=CENTROID_COLUMNS, numeric=CENTROID_COLUMNS)
        except KisscalError as exc:
            problems.append(str(exc))
    return problems
