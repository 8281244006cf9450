"""Calibration routes of ``kisscal calibrate``: one module per way a lab calibrates.

Each route takes a :class:`RouteInputs` and writes ``out/dlt/<camera>.json`` for the cameras
it calibrates (plus its own extra files); :func:`kisscal.session.calibrate.calibrate` picks
the route from the session, writes what every route shares (``dltdv.csv``,
``calibration.json``) and hands the result on. Everything downstream reads only those files.

Routes: :mod:`~kisscal.session.routes.rods` (surveyed rods, the seeds' method),
:mod:`~kisscal.session.routes.points` (control points given per camera),
:mod:`~kisscal.session.routes.wand` (a wand, on rods or with an axes object) and
:mod:`~kisscal.session.routes.target` (a known target matched from clicked seeds).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kisscal.detect import DetectionParams
from kisscal.grid import Linearisation
from kisscal.io.config import CameraConfig, SessionConfig
from kisscal.io.files import write_json
from kisscal.io.frames import camera_frames
from kisscal.io.store import SessionStore
from kisscal.session.ahead import Ahead
from kisscal.session.params import StageParams
from kisscal.session.progress import Echo
from kisscal.session.runner import camera_blobs, markers_detection


@dataclass(frozen=True)
class RouteInputs:
    """What every calibration route is given.

    Attributes
    ----------
    root : Path
        The session folder.
    config : SessionConfig
    cameras : tuple of CameraConfig
        The cameras to calibrate (all, or the one given with ``--camera``).
    linearisations : dict
        Each camera's current grid linearisation (identity without a grid).
    params : StageParams
    echo : Echo
        Where log lines go.
    workers : int or None
        Detection processes.
    ahead : Ahead or None
        The trials' blobs ``kisscal run`` detects in the background
        (:class:`kisscal.session.ahead.Ahead`).
    """

    root: Path
    config: SessionConfig
    cameras: tuple[CameraConfig, ...]
    linearisations: dict[str, Linearisation]
    params: StageParams
    echo: Echo
    workers: int | None = None
    ahead: Ahead | None = None

    @property
    def store(self) -> SessionStore:
        """Where the route writes (``out/dlt/`` above all) and keys its inputs."""
        return SessionStore(self.root)

    @property
    def whole_rig(self) -> bool:
        """True when every camera of the session is calibrated (rig-wide checks apply)."""
        return len(self.cameras) == len(self.config.cameras)


def frame_files(
    inputs: RouteInputs, pattern: str, what: str, fields: str | None = None
) -> dict[str, Sequence]:
    """Each camera's frames of a static calibration object (rods, axes, a target)."""
    root = inputs.config.root
    return {c.id: camera_frames(root, pattern, c.id, what, fields=fields) for c in inputs.cameras}


def marker_detection(inputs: RouteInputs) -> dict[str, DetectionParams]:
    """Each camera's detection settings for marker images (derived once, then kept)."""
    config, params, echo = inputs.config, inputs.params, inputs.echo
    return markers_detection(config, params, echo, inputs.cameras, inputs.workers)


def static_blobs(
    inputs: RouteInputs,
    frames: dict[str, Sequence],
    what: str,
    fields: str | None,
    detection: dict[str, DetectionParams],
) -> dict[str, list[NDArray[np.float64]]]:
    """Raw valid blob centroids of every frame of a static object, per camera (cached).

    ``what`` names the object in messages and in the cache (``rods``, ``axes`` ...).
    """
    chosen = {cam.id: frames[cam.id] for cam in inputs.cameras}
    blobs = camera_blobs(
        inputs.config, chosen, detection, fields, (what, what), inputs.echo, inputs.workers
    )
    return {cam: [b.valid_only().xy_px for b in found] for cam, found in blobs.items()}


def outputs_of(inputs: RouteInputs, route: str) -> bool:
    """True when every camera's ``dlt/<camera>.json`` was written by ``route``.

    A route's cache is valid only then: another route may have run since.
    """
    store = inputs.store
    for cam in inputs.cameras:
        doc = store.read_json(store.dlt_path(cam.id))
        if not isinstance(doc, dict) or doc.get("method") != route:
            return False
    return True


def write_check(inputs: RouteInputs, check: dict) -> None:
    """Write ``dlt/check.json`` for a route that keeps its own cache key elsewhere.

    The rods route's key beside the file is removed: the file is no longer its output.
    """
    path = inputs.store.calibration_file("check")
    write_json(path, check)
    inputs.store.forget(path)
