"""Detection settings of every camera, derived from the session's own images.

For each camera, a few frames of each of its image sets are surveyed
(:func:`kisscal.detect.configure.configure_detection`): its grid frames on their own
(``grid``) and everything else together (``markers``: rods, axes, calibration target,
trials). The camera's pixel aspect comes from its grid lattice when there is a grid
(:func:`kisscal.grid.lattice.lattice_pixel_aspect`, exact to a fraction of a percent),
otherwise from the shape of its markers. What ``[detection]`` (or the command line) gives
is used as given. The result, with the reason for every value, is written to
``out/detection/<camera>.json`` and kept: the settings are a property of the camera.
"""

from __future__ import annotations

import dataclasses
import functools
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.detect import DetectionParams
from kisscal.detect.configure import Choice, DetectionSetup, configure_detection
from kisscal.errors import KisscalError
from kisscal.grid.frames import dots_from_frames
from kisscal.grid.lattice import lattice_pixel_aspect
from kisscal.io.cache import cache_key
from kisscal.io.config import CameraConfig, SessionConfig
from kisscal.io.files import write_json
from kisscal.io.frames import camera_frames
from kisscal.session.inputs import image_sources, out_dir
from kisscal.session.parallel import each_camera
from kisscal.session.progress import Echo, quiet

#: Frames surveyed per image set (spread evenly over it) and per camera and kind at most.
FRAMES_PER_SET = 8
MAX_FRAMES = 24
#: A lattice aspect this close to 1 is square pixels (a grid 14 degrees off face-on).
LATTICE_SQUARE_TOLERANCE = 0.03
#: Bumped whenever the derivation changes, so cached settings are derived again.
DERIVATION_VERSION = 2


@dataclasses.dataclass(frozen=True)
class _Sample:
    """Frames of one camera and kind picked for the survey (decoded only when needed)."""

    sets: tuple[tuple[str, Sequence, tuple[int, ...]], ...]  # (what, frames, picked indices)
    camera: CameraConfig

    @property
    def frames(self) -> list[np.ndarray]:
        return [_sized(seq, i, self.camera) for _what, seq, picks in self.sets for i in picks]


def detection_given(config: SessionConfig, overrides: Mapping[str, Any] | None) -> dict[str, Any]:
    """The detection values the user gave: ``[detection]``, then the command line."""
    given = {**config.detection, **(overrides or {})}
    DetectionParams.from_layers(given)  # unknown names, bad values: one-line errors
    return given


def camera_detection(
    root: Path,
    config: SessionConfig,
    camera: CameraConfig,
    kind: str,
    given: Mapping[str, Any],
    echo: Echo = quiet,
) -> DetectionParams:
    """Detection parameters of one camera for its ``"grid"`` or ``"markers"`` images.

    Derived on first use and kept in ``out/detection/<camera>.json``: they are a property
    of the camera, so adding, fixing or dropping a trial later changes neither them nor
    anything detected with them. They are derived again when the values given in
    ``[detection]`` or the camera's image size change, or when the file is deleted.
    """
    path = out_dir(root) / "detection" / f"{camera.id}.json"
    current = _current(root, camera, kind, given)
    if current is not None:
        return current
    sample = _sample(config, camera, kind)
    if sample is None:
        raise KisscalError(f"camera {camera.id} has no {kind} images to detect")
    if kind == "grid":
        setup = _grid_setup(sample, given, config)
    else:
        aspect = given.get("pixel_aspect")
        if aspect is None and config.grid is not None:
            camera_detection(root, config, camera, "grid", given, echo)
            aspect = _read_document(path, camera)["kinds"]["grid"]["settings"]["pixel_aspect"]
            aspect = aspect["value"] if "lattice" in aspect["why"] else None
        why = "the grid's dot lattice"
        setup = configure_detection(sample.frames, given, pixel_aspect=aspect, aspect_why=why)
    doc = _read_document(path, camera)
    doc["kinds"][kind] = {**setup.as_dict(), "key": _key(camera, kind, given)}
    write_json(path, doc)
    echo(f"  detection {camera.id} {setup.summary()}")
    return setup.params


def _current(
    root: Path, camera: CameraConfig, kind: str, given: Mapping[str, Any]
) -> DetectionParams | None:
    """The camera's settings for ``kind`` as kept, if derived with the same given values."""
    doc = _read_document(out_dir(root) / "detection" / f"{camera.id}.json", camera)
    entry = doc["kinds"].get(kind)
    if entry is not None and entry.get("key") == _key(camera, kind, given):
        return _params_from_doc(entry, given)
    return None


def _key(camera: CameraConfig, kind: str, given: Mapping[str, Any]) -> str:
    """What a camera's settings for ``kind`` were derived from: they stand while it does."""
    return cache_key("detection", DERIVATION_VERSION, dict(given), camera.size_px, kind)


def _read_document(path: Path, camera: CameraConfig) -> dict[str, Any]:
    """The camera's detection document, or an empty one."""
    if path.is_file():
        doc = json.loads(path.read_text())
        if isinstance(doc, dict) and isinstance(doc.get("kinds"), dict):
            return doc
    return {"camera": camera.id, "size": list(camera.size_px or ()) or None, "kinds": {}}


def _survey_camera(
    root: Path, config: SessionConfig, given: Mapping[str, Any], cam: CameraConfig, say: Echo
) -> DetectionParams:
    """The marker detection survey of one camera, as :func:`each_camera` calls it."""
    return camera_detection(root, config, cam, "markers", given, say)


def markers_detection(
    root: Path,
    config: SessionConfig,
    given: Mapping[str, Any],
    echo: Echo = quiet,
    cameras: Sequence[CameraConfig] | None = None,
    workers: int | None = None,
) -> dict[str, DetectionParams]:
    """Each camera's detection parameters for its marker images (rods, trials, ...).

    Every camera of the session unless ``cameras`` says which; the cameras still to be
    surveyed are surveyed side by side in ``workers`` processes (default: one per core).
    """
    cameras = list(config.cameras if cameras is None else cameras)
    known = {c.id: _current(root, c, "markers", given) for c in cameras}
    todo = [c for c in cameras if known[c.id] is None]

    # a partial of a module-level function: spawned workers (Windows) receive it pickled
    survey = functools.partial(_survey_camera, root, config, dict(given))
    surveyed = each_camera(survey, todo, "detection settings", echo, workers) if todo else []
    known.update({c.id: p for c, p in zip(todo, surveyed, strict=True)})
    return {c.id: known[c.id] for c in cameras}  # type: ignore[misc]


def _grid_setup(sample: _Sample, given: Mapping[str, Any], config: SessionConfig) -> DetectionSetup:
    """Settings of a camera's grid frames, with its pixel aspect from the dot lattice."""
    frames = sample.frames
    why = "grid dots: never split"
    setup = configure_detection(frames, given, kind="grid", pixel_aspect=1.0, aspect_why=why)
    if "pixel_aspect" in given:
        return setup
    cell = float(config.sections.get("grid", {}).get("cell_aspect", 1.0))
    try:
        aspect = lattice_pixel_aspect(dots_from_frames(frames, setup.params), cell)
    except KisscalError:
        return setup  # no lattice in these frames: the markers will tell
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
    sets = []
    per_set = min(max(MAX_FRAMES // max(len(sources), 1), 3), FRAMES_PER_SET)
    for what, pattern, video, fields in sources:
        try:
            seq = camera_frames(config.root, pattern, camera.id, what, video, fields)
        except KisscalError:
            continue  # missing frames are reported by the stage that needs them
        n = len(seq)
        picks = tuple(int(i) for i in np.unique(np.linspace(0, n - 1, min(n, per_set)).astype(int)))
        if not picks:
            continue
        sets.append((what, seq, picks))
    return _Sample(tuple(sets), camera) if sets else None


def _sized(frames: Sequence, index: int, camera: CameraConfig) -> np.ndarray:
    """Frame ``index``, refused (naming its file) when it is not the camera's size."""
    image = frames[index]
    h, w = image.shape[:2]
    if camera.size_px is not None and (w, h) != tuple(camera.size_px):
        paths = getattr(frames, "paths", None)
        name = paths[index] if paths is not None else f"{getattr(frames, 'path', '')} frame {index}"
        raise KisscalError(
            f"{name}: {w} x {h} pixels, but camera {camera.id}'s frames are "
            f"{camera.size_px[0]} x {camera.size_px[1]}"
        )
    return image


def _params_from_doc(doc: Mapping[str, Any], given: Mapping[str, Any]) -> DetectionParams:
    values = {
        k: tuple(v["value"]) if isinstance(v["value"], list) else v["value"]
        for k, v in doc["settings"].items()
        if v["source"] != "given"
    }
    return DetectionParams.from_layers(values, given)


def describe_cameras(root: Path, cameras: Sequence[str]) -> dict[str, dict[str, Any]]:
    """The derived settings of each camera as written (for summaries and the report)."""
    docs = {}
    for cam in cameras:
        path = out_dir(root) / "detection" / f"{cam}.json"
        if path.is_file():
            docs[cam] = json.loads(path.read_text())
    return docs
