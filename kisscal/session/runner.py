"""The one runner of the session's stages: what a stage runs on, resolved in one place.

A stage module is handed its blobs; it never asks for its cameras' detection settings
nor detects. The runner resolves them: each camera's settings for its marker images
(kept in its record ``out/detection/<camera>.json`` when current, else surveyed from a
sample of its frames, the cameras side by side in the detector's pool,
:func:`kisscal.detect.sequence.surveyed`; the sampling and the grid's pixel aspect are
:mod:`kisscal.session.configure`'s), then each camera's blobs, detected with those
settings in one pool (:func:`kisscal.detect.detect_jobs`) and cached. A trial stage
(:class:`TrialStage`) is keyed on the trial's source files, its cameras' settings and
what the stage itself declares (:meth:`kisscal.io.store.SessionStore.key`), skipped
when its output is current, else handed its blobs (:func:`run_trial`). A session stage
whose cameras are independent (a grid fit reads only its camera's images and writes only
its camera's files) is run camera by camera in the same pool (:func:`each_camera`).
"""

from __future__ import annotations

import dataclasses
import functools
import os
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from kisscal.detect import Blobs, DetectionParams, ImageJob, detect_jobs
from kisscal.detect.configure import DetectionSetup
from kisscal.detect.sequence import SurveyJob, mapped, surveyed
from kisscal.errors import InputError, KisscalError, MissingDataError
from kisscal.io.cache import save_blob_frames
from kisscal.io.config import CameraConfig, SessionConfig, TrialConfig
from kisscal.io.detection_record import DetectionRecord, write_detection_record
from kisscal.io.store import SessionStore, TrialFiles
from kisscal.session.ahead import Ahead, blob_slot, image_job
from kisscal.session.configure import Sample, grid_setup, survey_sample
from kisscal.session.figures import handing_back, submit_packed
from kisscal.session.params import Overrides, StageParams, stage_params
from kisscal.session.progress import Echo, counted, quiet
from kisscal.session.trials import centroid_files, trial_frames_of, trial_input_files

#: Bumped whenever the derivation changes, so cached settings are derived again.
DERIVATION_VERSION = 4


def camera_detection(
    config: SessionConfig, camera: CameraConfig, kind: str, params: StageParams, echo: Echo = quiet
) -> DetectionParams:
    """Detection parameters of one camera for its ``"grid"`` or ``"markers"`` images.

    Derived on first use from the session's resolved parameters (``params``: what
    ``[detection]`` gives is kept as given) and written to ``out/detection/<camera>.json``,
    which later runs read back: the settings are a property of the camera, so adding,
    fixing or dropping a trial later changes neither them nor anything detected with
    them. They are derived again when the values given in ``[detection]`` or the camera's
    image size change, or when the file is deleted.
    """
    survey = _Survey(SessionStore(config.root), config, camera, params, echo)
    try:
        return survey.settings(kind).params
    finally:  # what was derived is kept, the grid's even when the markers' failed
        survey.write()


def markers_detection(
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
    store = SessionStore(config.root)
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


@dataclass(frozen=True)
class _Settings:
    """A camera's settings for one kind of image, and whether its pixel aspect was
    measured on its grid's dot lattice (grid images only)."""

    params: DetectionParams
    lattice_aspect: bool


@dataclass
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
            return self.derived(kind, grid_setup(self.sample(kind), self.params))
        return self.derived(kind, self.job(kind).derive())

    def sample(self, kind: str) -> Sample:
        """The frames the camera's ``kind`` settings are derived from."""
        sample = survey_sample(self.config, self.camera, kind)
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
    only pixel aspect of grid frames recorded as ``derived``: see
    :func:`kisscal.session.configure.grid_setup`)."""
    return kind == "grid" and aspect_source == "derived"


def camera_blobs(
    config: SessionConfig,
    frames: Mapping[str, Sequence[np.ndarray]],
    detection: Mapping[str, DetectionParams],
    fields: str | None,
    name: tuple[str, str],
    echo: Echo = quiet,
    workers: int | None = None,
    ahead: Ahead | None = None,
) -> dict[str, list[Blobs]]:
    """Blobs of every frame of each camera's ``frames``, from the cache when it is current.

    The cameras whose cache is stale are detected together, in one pool of processes
    (:func:`kisscal.detect.detect_jobs`): the workers decode and detect, and no core
    waits for the last frames of one camera before the next camera starts; a camera
    whose blobs ``kisscal run`` detected ahead is taken from there (``ahead``, the run's
    :class:`~kisscal.session.ahead.Ahead`). ``name`` is
    ``(cache stem, label)``: caches are ``out/cache/blobs/<stem>-<camera>.npz`` and
    messages say ``detect <label>``. A frame that cannot be read fails after the other
    cameras' blobs are cached.
    """
    stem, label = name
    sizes = {c.id: c.size_px for c in config.cameras}
    out: dict[str, list[Blobs]] = {}
    stale = []
    store = SessionStore(config.root)
    for cam, seq in frames.items():
        cache, key = blob_slot(store, stem, cam, seq, fields, detection[cam])
        if store.is_current(cache, key):
            out[cam] = store.blobs(stem, cam)
        else:
            stale.append(
                (cam, image_job(seq, cam, sizes[cam], detection[cam], workers), cache, key)
            )
    if out:
        echo(f"  detect {label}: {len(out)} of {len(frames)} cameras cached")
    t0 = time.perf_counter()
    failed: KisscalError | None = None
    here: list[int] = []  # the cameras detected here, not ahead
    for j, found in counted(_detected(stale, workers, here, ahead), f"detect {label}", len(stale)):
        cam, _s, cache, key = stale[j]
        if isinstance(found, KisscalError):
            failed = failed or found
            continue
        save_blob_frames(cache, found)
        store.mark_current(cache, key)
        out[cam] = found
    if failed is not None:
        raise failed
    _say_detected(echo, label, [stale[j][1] for j in here], time.perf_counter() - t0)
    ahead = [job for j, (_cam, job, _c, _k) in enumerate(stale) if j not in here]
    if ahead:
        n = sum(job.count for job in ahead)
        echo(f"  detect {label}: {len(ahead)} cameras, {n} frames, detected in the background")
    return {cam: out[cam] for cam in frames}


def _say_detected(echo: Echo, label: str, jobs: list[ImageJob], seconds: float) -> None:
    if jobs:
        n = sum(job.count for job in jobs)
        echo(
            f"  detect {label}: {len(jobs)} cameras, {n} frames in {seconds:.1f} s "
            f"({n / max(seconds, 1e-9):.0f} frames/s)"
        )


def _detected(
    stale: list[tuple[str, ImageJob, Path, str]],
    workers: int | None,
    here: list[int],
    ahead: Ahead | None,
) -> Iterator[tuple[int, list[Blobs] | KisscalError]]:
    """The blobs of every stale camera (by index): detected ahead in the background
    (:meth:`kisscal.session.ahead.Ahead.take`), else here, in one pool (their indices
    put in ``here``)."""
    for j, (_cam, _job, cache, key) in enumerate(stale):
        found = None if ahead is None else ahead.take(cache, key)
        if found is None:
            here.append(j)
        else:
            yield j, found
    for i, found in detect_jobs([stale[j][1] for j in here], workers):
        yield here[i], found


def trial_stem(trial: TrialConfig) -> str:
    """The stem of a trial's blob caches (:func:`camera_blobs`)."""
    return f"trial-{trial.name}"


def trial_blobs(
    config: SessionConfig,
    trial: TrialConfig,
    detection: dict[str, DetectionParams],
    echo: Echo,
    workers: int | None = None,
    ahead: Ahead | None = None,
) -> dict[str, list[NDArray]]:
    """Per camera, the raw (distorted) valid blob centroids of every field, as (n, 2) arrays.

    ``detection`` holds each camera's detection parameters (unused for centroid files);
    ``ahead`` the blobs ``kisscal run`` detected in the background (:func:`camera_blobs`).
    """
    if trial.source == "centroids":
        return centroid_files(config, trial)
    frames = trial_frames_of(config, trial)
    name = (trial_stem(trial), trial.name)
    blobs = camera_blobs(config, frames, detection, trial.fields, name, echo, workers, ahead)
    return {cam: [b.valid_only().xy_px for b in found] for cam, found in blobs.items()}


@dataclass(frozen=True)
class TrialRun:
    """What the runner hands a trial stage: the session, the trial and the session's
    resolved parameters but for the detection settings (the stage reads its own members
    of them; its blobs come detected)."""

    root: Path
    config: SessionConfig
    trial: TrialConfig
    params: StageParams
    echo: Echo = quiet

    @property
    def store(self) -> SessionStore:
        return SessionStore(self.root)

    @property
    def files(self) -> TrialFiles:
        return self.store.trial(self.trial.name)


@dataclass(frozen=True)
class TrialStage:
    """A trial stage as :func:`run_trial` runs it; the stage module gives the functions.

    Attributes
    ----------
    name : str
        The stage (first part of its key, and of its messages).
    inputs : callable
        ``inputs(run)``: what the stage needs besides its blobs (a tuple, keyed).
    output : callable
        ``output(files)``: the output its key is kept beside, and whether the other
        outputs are there too.
    cached : callable
        ``cached(run)``: the stage's result when its output is current.
    compute : callable
        ``compute(run, inputs, blobs)``: the result, its outputs written.
    without_blobs : callable
        ``without_blobs(run)``: a trial of neither frames nor centroids (a C3D file).
    """

    name: str
    inputs: Callable[[TrialRun], tuple]
    output: Callable[[TrialFiles], tuple[Path, bool]]
    cached: Callable[[TrialRun], Any]
    compute: Callable[[TrialRun, tuple, dict[str, list[NDArray]]], Any]
    without_blobs: Callable[[TrialRun], Any]


def run_trial(
    stage: TrialStage,
    config: SessionConfig,
    trial_name: str,
    overrides: Overrides | None = None,
    echo: Echo = quiet,
    workers: int | None = None,
    ahead: Ahead | None = None,
) -> Any:
    """Run ``stage`` on one trial: keyed on the trial's source files, its cameras' marker
    settings (:func:`markers_detection`, for images and video) and ``stage.inputs``;
    skipped when its output is current, else handed the trial's blobs (from ``ahead``
    when ``kisscal run`` detected them in the background)."""
    trial = config.trial(trial_name)
    params = stage_params(config, overrides)
    # the stage is handed blobs, never detection settings: [detection]'s values are not a
    # camera's settings (those are derived per camera), so no stage can use them by mistake
    stage_own = dataclasses.replace(params, detection=DetectionParams(), detection_given={})
    run = TrialRun(config.root, config, trial, stage_own, echo)
    if trial.source == "c3d":
        return stage.without_blobs(run)
    inputs = stage.inputs(run)
    imaged = trial.source in ("images", "video")
    detection = markers_detection(config, params, echo, workers=workers) if imaged else {}
    store = run.store
    key = store.key(stage.name, trial_input_files(config, trial), detection, *inputs)
    output, complete = stage.output(run.files)
    if store.is_current(output, key) and complete:
        echo(f"  {stage.name} {trial.name}: cached")
        return stage.cached(run)
    blobs = trial_blobs(config, trial, detection, echo, workers, ahead)
    result = stage.compute(run, inputs, blobs)
    store.mark_current(output, key)
    return result


T = TypeVar("T")
R = TypeVar("R")


def run_keyed(
    store: SessionStore,
    output: Path,
    inputs: tuple,
    cached: Callable[[], R | None],
    compute: Callable[[], R] | None = None,
) -> R | None:
    """A session stage (a linearisation, a calibration route) keyed on ``inputs`` as
    :func:`run_trial` keys a trial's: ``cached()`` while ``output``'s key matches (and it
    is not None: another route may have written since), else ``compute()`` (None without
    one) and the key kept beside ``output``."""
    key = store.key(*inputs)
    if store.is_current(output, key) and (kept := cached()) is not None:
        return kept
    if compute is None:
        return None
    result = compute()
    store.mark_current(output, key)
    return result


#: What a worker returns for one item: the result (or the KisscalError it raised), what it
#: said, and the figures it drew (pickled, for the parent's figure process).
_Done = tuple[Any, list[str], list[bytes]]


def _call(work: Callable[[Any, Echo], Any], item: Any) -> _Done:
    """``work(item)``'s result (or the KisscalError it raised), what it said and the
    figures it drew."""
    said: list[str] = []
    with handing_back() as figures:
        try:
            result = work(item, said.append)
        except KisscalError as exc:
            result = exc
    return result, said, figures


def each_camera(
    work: Callable[[T, Echo], R],
    items: Sequence[T],
    stage: str,
    echo: Echo,
    workers: int | None = None,
) -> list[R]:
    """``work(item, echo)`` for every item, in parallel processes; the results in order.

    The detector's pool (:func:`kisscal.detect.sequence.mapped`): workers are forked, so
    ``work`` and its inputs are inherited, not pickled (spawned workers, on Windows, get
    them pickled once: ``work`` must then be a module-level function or a
    ``functools.partial`` of one, else the items are done in this process). Every
    message a worker says is repeated here, item by item in order, and every figure it
    drew is handed to this process's figure process
    (:func:`kisscal.session.figures.handing_back`). ``workers`` None uses every core, 1
    works in this process. The first :class:`KisscalError` an item raised is raised
    again once every item is done (the others' files are written).
    """
    n = min(workers or os.cpu_count() or 1, len(items))
    results: list[R] = []
    failed: KisscalError | None = None
    done = mapped(functools.partial(_call, work), items, n)
    for result, said, figures in counted(done, stage, len(items)):
        for line in said:
            echo(line)
        for packed in figures:
            submit_packed(packed)
        if isinstance(result, KisscalError):
            failed = failed or result
        results.append(result)
    if failed is not None:
        raise failed
    return results
