"""Detection settings of every camera, derived from the session's own images.

For each camera, a few frames of each of its image sets are surveyed
(:func:`kisscal.detect.configure.configure_detection`): its grid frames on their own
(``grid``) and everything else together (``markers``: rods, axes, calibration target,
trials). The camera's pixel aspect comes from its grid lattice when there is a grid
(:func:`kisscal.grid.lattice.lattice_pixel_aspect`, exact to a fraction of a percent),
otherwise from the shape of its markers. What ``[detection]`` (or the command line) gives
is used as given. The result, with the reason for every value, is written to
``out/detection/<camera>.json`` and cached against the sampled files and the given values.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.detect import DetectionParams
from kisscal.detect.configure import Choice, DetectionSetup, configure_detection
from kisscal.errors import KisscalError
from kisscal.io.cache import cache_key, is_current, mark_current
from kisscal.io.config import CameraConfig, SessionConfig
from kisscal.io.files import write_json
from kisscal.io.frames import camera_frames
from kisscal.session.inputs import file_keys, image_sources, out_dir
from kisscal.session.progress import Echo, quiet

#: Frames surveyed per image set (spread evenly over it) and per camera and kind at most.
FRAMES_PER_SET = 8
MAX_FRAMES = 24
#: Bumped whenever the derivation changes, so cached settings are derived again.
DERIVATION_VERSION = 1


@dataclasses.dataclass(frozen=True)
class _Sample:
    """Frames of one camera and kind picked for the survey (decoded only when needed)."""

    sets: tuple[tuple[str, Sequence, tuple[int, ...]], ...]  # (what, frames, picked indices)
    keys: tuple[Any, ...]
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

    Derived on first use and kept in ``out/detection/<camera>.json`` until the sampled
    frames or the given values change.
    """
    path = out_dir(root) / "detection" / f"{camera.id}.json"
    samples = {k: _sample(config, camera, k) for k in ("grid", "markers")}
    key = cache_key(
        "detection",
        DERIVATION_VERSION,
        dict(given),
        {k: s.keys for k, s in samples.items() if s is not None},
    )
    if is_current(path, key):
        doc = json.loads(path.read_text())
        if kind in doc.get("kinds", {}):
            return _params_from_doc(doc["kinds"][kind], given)
    setups = derive_camera(samples, given, config)
    doc = _document(camera, setups)
    write_json(path, doc)
    mark_current(path, key)
    for setup in setups.values():
        echo(f"  detection {camera.id} {setup.summary()}")
    if kind not in setups:
        raise KisscalError(f"camera {camera.id} has no {kind} images to detect")
    return setups[kind].params


def markers_detection(
    root: Path, config: SessionConfig, given: Mapping[str, Any], echo: Echo = quiet
) -> dict[str, DetectionParams]:
    """Every camera's detection parameters for its marker images (rods, trials, ...)."""
    return {
        cam.id: camera_detection(root, config, cam, "markers", given, echo)
        for cam in config.cameras
    }


def derive_camera(
    samples: Mapping[str, _Sample | None], given: Mapping[str, Any], config: SessionConfig
) -> dict[str, DetectionSetup]:
    """The setups of one camera's grid and marker images (those it has)."""
    from kisscal.grid.frames import dots_from_frames
    from kisscal.grid.lattice import lattice_pixel_aspect

    setups: dict[str, DetectionSetup] = {}
    aspect = given.get("pixel_aspect")
    grid = samples.get("grid")
    if grid is not None:
        setup = configure_detection(
            grid.frames, given, kind="grid", pixel_aspect=1.0, aspect_why="grid dots: no split"
        )
        if aspect is None:
            dots = dots_from_frames(grid.frames, setup.params)
            cell = float(config.sections.get("grid", {}).get("cell_aspect", 1.0))
            try:
                aspect = round(lattice_pixel_aspect(dots, cell), 4)
                setup = _with_lattice_aspect(setup, aspect)
            except KisscalError:
                aspect = None  # no lattice in these frames: the markers will tell
        setups["grid"] = setup
    markers = samples.get("markers")
    if markers is not None:
        setups["markers"] = configure_detection(
            markers.frames, given, pixel_aspect=aspect, aspect_why="the grid's dot lattice"
        )
    return setups


def _with_lattice_aspect(setup: DetectionSetup, aspect: float) -> DetectionSetup:
    """``setup`` with the camera's pixel aspect measured on its grid lattice."""
    choices = dict(setup.choices)
    why = "x over y step of the grid's dot lattice"
    choices["pixel_aspect"] = Choice(aspect, "derived", why)
    params = setup.params.replace(pixel_aspect=aspect)
    return dataclasses.replace(setup, params=params, choices=choices)


def _sample(config: SessionConfig, camera: CameraConfig, kind: str) -> _Sample | None:
    """Up to :data:`MAX_FRAMES` frames of the camera's ``kind`` images, spread evenly."""
    sources = [
        (what, pattern, video)
        for what, pattern, video in image_sources(config)
        if (what == "grid") == (kind == "grid")
    ]
    sets, keys = [], []
    per_set = min(max(MAX_FRAMES // max(len(sources), 1), 3), FRAMES_PER_SET)
    for what, pattern, video in sources:
        try:
            seq = camera_frames(config.root, pattern, camera.id, what, video=video)
        except KisscalError:
            continue  # missing frames are reported by the stage that needs them
        n = len(seq)
        picks = tuple(int(i) for i in np.unique(np.linspace(0, n - 1, min(n, per_set)).astype(int)))
        if not picks:
            continue
        sets.append((what, seq, picks))
        paths = getattr(seq, "paths", None)
        files = [paths[i] for i in picks] if paths is not None else [Path(seq.path)]
        keys.append(file_keys(files, config.root))
    return _Sample(tuple(sets), tuple(keys), camera) if sets else None


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


def _document(camera: CameraConfig, setups: Mapping[str, DetectionSetup]) -> dict[str, Any]:
    return {
        "camera": camera.id,
        "size": list(camera.size_px) if camera.size_px else None,
        "kinds": {k: s.as_dict() for k, s in setups.items()},
    }


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
