"""Detection settings of every camera, derived from the session's own images.

For each camera, a few frames of each of its image sets are surveyed
(:func:`kisscal.detect.configure.configure_detection`): its grid frames on their own
(``grid``) and everything else together (``markers``: rods, axes, calibration target,
trials), the cameras' marker images side by side in the detector's pool
(:func:`kisscal.detect.sequence.surveyed`). The camera's pixel aspect comes from
its grid lattice when there is a grid (:func:`kisscal.grid.lattice.lattice_pixel_aspect`,
exact to a fraction of a percent), otherwise from the shape of its markers. What
``[detection]`` (or the command line) gives is used as given: it comes typed from the
session's resolved parameters (:func:`kisscal.session.params.stage_params`), never from
the raw table. The result, with the reason for every value, is written to
``out/detection/<camera>.json`` and kept: the settings are a property of the camera.
The running session uses the settings it derived in memory; the file is read only to
find settings an earlier run derived.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from kisscal.detect import DetectionParams
from kisscal.detect.configure import Choice, DetectionSetup, configure_detection
from kisscal.detect.sequence import SurveyJob, mapped, surveyed
from kisscal.errors import InputError, KisscalError, MissingDataError
from kisscal.grid.frames import dots_from_frames
from kisscal.grid.lattice import lattice_pixel_aspect
from kisscal.io.config import CameraConfig, SessionConfig
from kisscal.io.detection_record import DetectionRecord, write_detection_record
from kisscal.io.frames import camera_frames
from kisscal.io.store import SessionStore
from kisscal.session.inputs import image_sources
from kisscal.session.params import StageParams
from kisscal.session.progress import Echo, counted, quiet

#: Frames surveyed per image set (spread evenly over it) and per camera and kind at most.
FRAMES_PER_SET = 8
MAX_FRAMES = 24
#: A lattice aspect this close to 1 is square pixels (a grid 14 degrees off face-on).
LATTICE_SQUARE_TOLERANCE = 0.03
#: Bumped whenever the derivation changes, so cached settings are derived again.
DERIVATION_VERSION = 4


@dataclasses.dataclass(frozen=True)
class _Sample:
    """Frames of one camera and kind picked for the survey (decoded only when needed)."""

    picks: tuple[tuple[Sequence, int], ...]  # (a set of frames, an index picked in it)
    camera: CameraConfig

    def frame(self, k: int) -> np.ndarray:
        """Picked frame ``k``, decoded and checked for the camera's size."""
        seq, i = self.picks[k]
        return _sized(seq, i, self.camera)

    @property
    def frames(self) -> list[np.ndarray]:
        return [self.frame(k) for k in range(len(self.picks))]


def camera_detection(
    root: Path,
    config: SessionConfig,
    camera: CameraConfig,
    kind: str,
    params: StageParams,
    echo: Echo = quiet,
) -> DetectionParams:
    """Detection parameters of one camera for its ``"grid"`` or ``"markers"`` images.

    Derived on first use from the session's resolved parameters (``params``: what
    ``[detection]`` gives is kept as given) and written to ``out/detection/<camera>.json``,
    which later runs read back: the settings are a property of the camera, so adding,
    fixing or dropping a trial later changes neither them nor anything detected with
    them. They are derived again when the values given in ``[detection]`` or the camera's
    image size change, or when the file is deleted.
    """
    survey = _Survey(SessionStore(root), config, camera, params, echo)
    try:
        return survey.settings(kind).params
    finally:  # what was derived is kept, the grid's even when the markers' failed
        survey.write()


def markers_detection(
    root: Path,
    config: SessionConfig,
    params: StageParams,
    echo: Echo = quiet,
    cameras: Sequence[CameraConfig] | None = None,
    workers: int | None = None,
) -> dict[str, DetectionParams]:
    """Each camera's detection parameters for its marker images (rods, trials, ...).

    Every camera of the session unless ``cameras`` says which: as kept in its record
    when current, else derived from a sample of its frames, the cameras side by side in
    ``workers`` processes (default: one per core; :func:`kisscal.detect.sequence.surveyed`)
    and recorded. The first error a camera raised is raised again once the others'
    settings are recorded.
    """
    store = SessionStore(root)
    chosen = config.cameras if cameras is None else cameras
    surveys = [_Survey(store, config, c, params, echo) for c in chosen]
    known = {s.camera.id: k.params for s in surveys if (k := s.kept("markers")) is not None}
    failed: list[KisscalError] = []
    todo = []
    for survey in (s for s in surveys if s.camera.id not in known):
        try:
            todo.append((survey, survey.job("markers")))
        except KisscalError as exc:  # no marker images: the others are surveyed still
            failed.append(exc)
            survey.write()  # a grid's settings derived for its aspect are kept
    jobs = [job for _survey, job in todo]
    done = mapped(surveyed, jobs, workers)
    setups = counted(done, "detection settings", len(jobs)) if jobs else []
    for (survey, _job), setup in zip(todo, setups, strict=True):
        if isinstance(setup, KisscalError):
            failed.append(setup)
        else:
            known[survey.camera.id] = survey.derived("markers", setup).params
        survey.write()
    if failed:
        raise failed[0]
    return {s.camera.id: known[s.camera.id] for s in surveys}


@dataclasses.dataclass(frozen=True)
class _Settings:
    """A camera's settings for one kind of image, and whether its pixel aspect was
    measured on its grid's dot lattice (grid images only)."""

    params: DetectionParams
    lattice_aspect: bool


@dataclasses.dataclass
class _Survey:
    """One camera's detection settings: what the session gives, its record (the settings
    kept) and the settings derived in this run (recorded by :meth:`write`)."""

    store: SessionStore
    config: SessionConfig
    camera: CameraConfig
    params: StageParams
    echo: Echo = quiet
    record: DetectionRecord = dataclasses.field(init=False)
    new: dict[str, tuple[DetectionSetup, str]] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        """Start from the camera's record; an empty one when the file is missing or
        unreadable (its settings are then derived again and the file rewritten)."""
        try:
            record = self.store.detection_record(self.camera.id)
        except InputError:
            record = None
        self.record = record or DetectionRecord(self.camera.id, self.camera.size_px)

    def settings(self, kind: str) -> _Settings:
        """The camera's settings for ``kind``: as kept in the record when current, else
        derived in this process."""
        kept = self.kept(kind)
        if kept is not None:
            return kept
        if kind == "grid":
            return self.derived(kind, _grid_setup(self.sample(kind), self.params))
        return self.derived(kind, self.job(kind).derive())

    def sample(self, kind: str) -> _Sample:
        """The frames the camera's ``kind`` settings are derived from."""
        sample = _sample(self.config, self.camera, kind)
        if sample is None:
            raise MissingDataError(f"camera {self.camera.id} has no {kind} images to detect")
        return sample

    def job(self, kind: str) -> SurveyJob:
        """The survey of the camera's marker images: its sample and what is given, with
        the pixel aspect of its grid's lattice (derived first when not kept)."""
        sample, given = self.sample(kind), self.params.detection_given
        aspect = None
        if "pixel_aspect" not in given and self.config.grid is not None:
            grid = self.settings("grid")
            aspect = grid.params.pixel_aspect if grid.lattice_aspect else None
        why = "the grid's dot lattice"
        return SurveyJob(sample.frame, len(sample.picks), given, "markers", aspect, why)

    def derived(self, kind: str, setup: DetectionSetup) -> _Settings:
        """Settings derived for ``kind`` in this run, said and kept for the record."""
        self.new[kind] = (setup, self.key(kind))
        self.echo(f"  detection {self.camera.id} {setup.summary()}")
        lattice = _on_lattice(kind, setup.choices["pixel_aspect"].source)
        return _Settings(setup.params, lattice)

    def write(self) -> None:
        """Record the settings derived in this run (nothing when none were)."""
        if self.new:
            path = self.store.detection_path(self.camera.id)
            write_detection_record(path, self.record, self.new)

    def kept(self, kind: str) -> _Settings | None:
        """The camera's settings for ``kind`` as kept, if derived with the same given
        values."""
        entry = self.record.kinds.get(kind)
        if entry is None or entry.key != self.key(kind):
            return None
        derived = entry.values(sources=("derived", "default"))
        lattice = _on_lattice(kind, entry.source("pixel_aspect"))
        return _Settings(self.params.detection.replace(**derived), lattice)

    def key(self, kind: str) -> str:
        """What the settings for ``kind`` were derived from: they stand while it does."""
        given = dict(self.params.detection_given)
        return self.store.key("detection", DERIVATION_VERSION, given, self.camera.size_px, kind)


def _on_lattice(kind: str, aspect_source: str) -> bool:
    """True when a grid's settings hold a pixel aspect measured on its dot lattice (the
    only pixel aspect of grid frames recorded as ``derived``: see :func:`_grid_setup`)."""
    return kind == "grid" and aspect_source == "derived"


def _grid_setup(sample: _Sample, params: StageParams) -> DetectionSetup:
    """Settings of a camera's grid frames, with its pixel aspect from the dot lattice.

    Only a pixel aspect measured on the lattice is recorded as ``derived``; without a
    lattice the grid frames are detected with square pixels, recorded as ``default``, and
    the camera's marker images measure its aspect themselves.
    """

    frames, given = sample.frames, params.detection_given
    why = "grid dots: never split"
    setup = configure_detection(frames, given, kind="grid", pixel_aspect=1.0, aspect_why=why)
    if "pixel_aspect" in given:
        return setup
    try:
        aspect = lattice_pixel_aspect(
            dots_from_frames(frames, setup.params), params.grid.cell_aspect
        )
    except KisscalError:  # no lattice in these frames: the markers will tell
        why = "no dot lattice in the grid frames: square pixels assumed for them"
        choices = {**setup.choices, "pixel_aspect": Choice(1.0, "default", why)}
        return dataclasses.replace(setup, choices=choices)
    # a grid tilted by t reads the aspect off by up to 1 - cos t: within 3 % it is square
    aspect = 1.0 if abs(aspect - 1.0) <= LATTICE_SQUARE_TOLERANCE else round(aspect, 4)
    return _with_lattice_aspect(setup, aspect)


def _with_lattice_aspect(setup: DetectionSetup, aspect: float) -> DetectionSetup:
    """``setup`` with the camera's pixel aspect measured on its grid lattice."""
    choices = dict(setup.choices)
    why = "x over y step of the grid's dot lattice"
    choices["pixel_aspect"] = Choice(aspect, "derived", why)
    params = setup.params.replace(pixel_aspect=aspect)
    return dataclasses.replace(setup, params=params, choices=choices)


def _sample(config: SessionConfig, camera: CameraConfig, kind: str) -> _Sample | None:
    """Up to :data:`MAX_FRAMES` frames of the camera's ``kind`` images, spread evenly."""
    # a known target's photographs (dots on a lit plate) are not marker images
    sources = [
        src
        for src in image_sources(config)
        if (src[0] == "grid") == (kind == "grid") and src[0] != "calibration"
    ]
    picks: list[tuple[Sequence, int]] = []
    per_set = min(max(MAX_FRAMES // max(len(sources), 1), 3), FRAMES_PER_SET)
    for what, pattern, video, fields in sources:
        try:
            seq = camera_frames(config.root, pattern, camera.id, what, video, fields)
        except KisscalError:
            continue  # missing frames are reported by the stage that needs them
        n = len(seq)
        picked = np.unique(np.linspace(0, n - 1, min(n, per_set)).astype(int))
        picks += [(seq, int(i)) for i in picked]
    return _Sample(tuple(picks), camera) if picks else None


def _sized(frames: Sequence, index: int, camera: CameraConfig) -> np.ndarray:
    """Frame ``index``, refused (naming its file) when it is not the camera's size."""
    image = frames[index]
    h, w = image.shape[:2]
    if camera.size_px is not None and (w, h) != tuple(camera.size_px):
        paths = getattr(frames, "paths", None)
        name = paths[index] if paths is not None else f"{getattr(frames, 'path', '')} frame {index}"
        raise InputError(
            f"{name}: {w} x {h} pixels, but camera {camera.id}'s frames are "
            f"{camera.size_px[0]} x {camera.size_px[1]}"
        )
    return image
