"""The one owner of a session's ``out/`` folder: every path of its layout, the typed
readers of what the stages wrote, and the one function that keys a stage's inputs.

The layout is the public contract of DESIGN.md (versions 1 to 3); this module only names
it. Nothing outside it joins a path under ``out/`` by hand (``tests/test_structure.py``
checks), so a file moves, or a reader changes, in one place.

A stage's output is reused only when the key stored beside it (``<file>.key``) matches
the key of the current inputs and parameters: :meth:`SessionStore.key` computes it from
any mix of dataclasses, arrays, input files (by path inside the session, size and
modification time), linearisations and rigs; :meth:`SessionStore.is_current` and
:meth:`SessionStore.mark_current` compare and record it. The key file is written after
the output (both atomically), so an interrupted run never pairs an old key with a new
output or the other way round.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.detect import Blobs
from kisscal.errors import InputError, MissingDataError
from kisscal.grid.poly import Linearisation
from kisscal.io.cache import load_blob_frames
from kisscal.io.detection_record import DetectionRecord, read_detection_record
from kisscal.io.dltfiles import DltFile, read_dlt_json
from kisscal.io.files import read_json, write_text
from kisscal.io.linearisation import read_linearisation, read_linearisation_doc
from kisscal.io.points2d import Points2DFile, read_points2d
from kisscal.io.points3d import Points3DFile, read_points3d
from kisscal.io.trajectories import TrajectoryTable, read_trajectories_csv
from kisscal.rig import Rig


@dataclass(frozen=True)
class TrialFiles:
    """The files of one trial under ``out/trials/<trial>/`` (DESIGN.md, contract v1-v3)."""

    folder: Path

    @property
    def points3d(self) -> Path:
        """``points3d.csv``: ``field,x_mm,y_mm,z_mm,n_cameras,rms_px``."""
        return self.folder / "points3d.csv"

    @property
    def points2d(self) -> Path:
        """``points2d.csv``: the 2D input of other triangulators."""
        return self.folder / "points2d.csv"

    @property
    def recon(self) -> Path:
        """``recon.json``: the reconstruction's counts and warnings."""
        return self.folder / "recon.json"

    def trajectories(self, suffix: str = ".csv") -> Path:
        """``trajectories.csv`` (or ``.c3d``, ``.trc``)."""
        return self.folder / f"trajectories{suffix}"

    @property
    def trajectory_cameras(self) -> Path:
        """``trajectories_cameras.csv``: which cameras saw each sample."""
        return self.folder / "trajectories_cameras.csv"

    @property
    def tracking(self) -> Path:
        """``tracking.json``: the tracker's summary."""
        return self.folder / "tracking.json"

    @property
    def sweep(self) -> Path:
        """``sweep.csv``: a tracking-parameter sweep."""
        return self.folder / "sweep.csv"

    @property
    def template(self) -> Path:
        """``subject_template.json``: a static trial's labelled standing pose."""
        return self.folder / "subject_template.json"

    @property
    def events(self) -> Path:
        """``events.csv``: ``side,event,field,time_s``."""
        return self.folder / "events.csv"

    @property
    def spatiotemporal(self) -> Path:
        """``spatiotemporal.csv``: cadence, speed, stride and step lengths, stance."""
        return self.folder / "spatiotemporal.csv"

    @property
    def gait(self) -> Path:
        """``gait.json``: the gait stage's summary."""
        return self.folder / "gait.json"


class SessionStore:
    """Where everything of the session at ``root`` is written, and how it is read back.

    Parameters
    ----------
    root : path
        The session folder (the one holding ``session.toml``).
    """

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        self.out = self.root / "out"

    def __repr__(self) -> str:
        return f"SessionStore({str(self.root)!r})"

    # -- the layout ------------------------------------------------------------------
    def detection_path(self, camera: str) -> Path:
        """``detection/<camera>.json``: the detection settings derived for a camera."""
        return self.out / "detection" / f"{camera}.json"

    def linearisation_path(self, camera: str) -> Path:
        """``linearisation/<camera>.json`` (contract v1)."""
        return self.out / "linearisation" / f"{camera}.json"

    @property
    def dlt_dir(self) -> Path:
        """``dlt/``: the calibration's files."""
        return self.out / "dlt"

    def dlt_path(self, camera: str) -> Path:
        """``dlt/<camera>.json`` (contract v1)."""
        return self.dlt_dir / f"{camera}.json"

    def calibration_file(self, name: str) -> Path:
        """``dlt/<name>.json`` beside the cameras': ``check``, ``wand``, ``target`` or
        ``calibration`` (the route and options that wrote the rest)."""
        if name not in ("check", "wand", "target", "calibration"):
            raise InputError(f"no calibration file {name!r} in the out/ layout")
        return self.dlt_dir / f"{name}.json"

    @property
    def dltdv_path(self) -> Path:
        """``dlt/dltdv.csv``: 11 rows, a column per camera."""
        return self.dlt_dir / "dltdv.csv"

    @property
    def cameras_toml_path(self) -> Path:
        """``cameras.toml``: the anipose / Pose2Sim calibration."""
        return self.out / "cameras.toml"

    @property
    def pose2sim_path(self) -> Path:
        """``pose2sim/Calib_kisscal.toml``: Pose2Sim's calibration (metres)."""
        return self.out / "pose2sim" / "Calib_kisscal.toml"

    @property
    def opencv_dir(self) -> Path:
        """``opencv/``: one OpenCV YAML file per camera."""
        return self.out / "opencv"

    @property
    def exports_path(self) -> Path:
        """``exports.json``: how closely the exports follow kisscal's cameras."""
        return self.out / "exports.json"

    def blobs_cache(self, stem: str, camera: str) -> Path:
        """``cache/blobs/<stem>-<camera>.npz``: the blobs of a set of frames."""
        return self.out / "cache" / "blobs" / f"{stem}-{camera}.npz"

    def trial(self, name: str) -> TrialFiles:
        """The files of trial ``name``."""
        return TrialFiles(self.out / "trials" / name)

    @property
    def figures_dir(self) -> Path:
        """``figures/``: every stage figure."""
        return self.out / "figures"

    def figure_path(self, name: str) -> Path:
        """``figures/<name>.png``."""
        return self.figures_dir / f"{name}.png"

    @property
    def summary_path(self) -> Path:
        """``summary.json``: every figure a user or CI checks."""
        return self.out / "summary.json"

    @property
    def limits_path(self) -> Path:
        """``limits.json``: the limits ``kisscal check`` judged against."""
        return self.out / "limits.json"

    @property
    def report_path(self) -> Path:
        """``report.html``."""
        return self.out / "report.html"

    def has_results(self) -> bool:
        """True once a stage has written something a report can show."""
        patterns = ("summary.json", "linearisation/*.json", "dlt/*.json")
        return any(any(self.out.glob(pattern)) for pattern in patterns)

    # -- currency --------------------------------------------------------------------
    def key(self, *parts: Any) -> str:
        """The key of a stage's inputs: a short hash of ``parts``.

        Parts may be dataclasses (parameters), arrays, mappings and sequences of them,
        input files (a :class:`~pathlib.Path`: its path inside the session, so that a
        moved or copied session keeps its cache, its size and modification time), a
        :class:`~kisscal.grid.poly.Linearisation` (its coefficients and normalisation)
        or a :class:`~kisscal.rig.Rig` (its linearisations, DLTs and lens terms).
        """
        text = json.dumps(self._canonical(list(parts)), sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:20]

    def _canonical(self, obj: Any) -> Any:
        if isinstance(obj, Linearisation):
            return [self._canonical(a) for a in (obj.x, obj.y, obj.center_px, obj.scale_px)]
        if isinstance(obj, Rig):
            return [[c.id, self._canonical([c.dlt, c.kolahi, c.linearisation])] for c in obj]
        if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
            return {type(obj).__name__: self._canonical(dataclasses.asdict(obj))}
        if isinstance(obj, dict):
            items = sorted(obj.items(), key=lambda kv: str(kv[0]))
            return {str(k): self._canonical(v) for k, v in items}
        if isinstance(obj, (list, tuple)):
            return [self._canonical(v) for v in obj]
        if isinstance(obj, np.ndarray):
            digest = hashlib.sha256(np.ascontiguousarray(obj).tobytes()).hexdigest()
            return digest + str(obj.shape)
        if isinstance(obj, Path):
            st = os.stat(obj)
            return [self._inside(obj), st.st_size, st.st_mtime_ns]
        if isinstance(obj, np.generic):
            return obj.item()
        return obj

    def _inside(self, path: Path) -> str:
        """``path`` inside the session (POSIX form), or whole when it is outside: what
        ``relative_to`` gives, with its parts compared directly when they match (a
        trial's key names thousands of files, and ``relative_to`` parses the root anew
        for each)."""
        root, parts = self.root.parts, path.parts
        if root and parts[: len(root)] == root:
            return "/".join(parts[len(root) :]) or "."
        return (path.relative_to(self.root) if path.is_relative_to(self.root) else path).as_posix()

    @staticmethod
    def is_current(output: Path, key: str) -> bool:
        """True when ``output`` exists and was written for ``key``."""
        key_file = output.with_name(output.name + ".key")
        return output.exists() and key_file.is_file() and key_file.read_text().strip() == key

    @staticmethod
    def mark_current(output: Path, key: str) -> None:
        """Record that ``output`` (already written) belongs to ``key``."""
        write_text(output.with_name(output.name + ".key"), key + "\n")

    @staticmethod
    def forget(output: Path) -> None:
        """Drop the key of ``output``: the file stays, but no stage will reuse it."""
        output.with_name(output.name + ".key").unlink(missing_ok=True)

    # -- typed readers ---------------------------------------------------------------
    def read_json(self, path: Path) -> Any:
        """A JSON file of the store, or None when there is none (see
        :func:`kisscal.io.files.read_json`)."""
        return read_json(path)

    def linearisation(self, camera: str) -> Linearisation:
        """The linearisation written for ``camera`` (a :class:`KisscalError` when none)."""
        return read_linearisation(self.linearisation_path(camera))[1]

    def linearisation_doc(self, camera: str) -> dict[str, Any] | None:
        """The whole linearisation document of ``camera``, or None when there is none."""
        return read_linearisation_doc(self.linearisation_path(camera))

    def dlt(self, camera: str) -> DltFile:
        """The DLT written for ``camera`` (a :class:`KisscalError` when none)."""
        return read_dlt_json(self.dlt_path(camera))

    def calibration_doc(self, name: str) -> dict[str, Any] | None:
        """``dlt/<name>.json`` (see :meth:`calibration_file`), or None when there is none."""
        return self.read_json(self.calibration_file(name))

    def detection_record(self, camera: str) -> DetectionRecord | None:
        """The detection settings derived for ``camera``, or None when there are none
        (an :class:`~kisscal.errors.InputError` when the file is not such a record)."""
        return read_detection_record(self.detection_path(camera))

    def reconstructed(self, trial: str) -> Path:
        """``points3d.csv`` of ``trial``, which must exist (a
        :class:`~kisscal.errors.MissingDataError` naming the command that writes it)."""
        path = self.trial(trial).points3d
        if not path.is_file():
            raise MissingDataError(
                f"{path}: missing; run `kisscal reconstruct {self.root} {trial}` first"
            )
        return path

    def points3d(self, trial: str) -> Points3DFile:
        """The 3D points of ``trial`` (see :meth:`reconstructed`)."""
        return read_points3d(self.reconstructed(trial))

    def points2d(self, trial: str) -> Points2DFile:
        """The 2D observations of ``trial`` and the 3D point each went into."""
        return read_points2d(self.trial(trial).points2d)

    def trajectories(self, trial: str) -> TrajectoryTable:
        """The labelled trajectories of ``trial`` (``trajectories.csv``)."""
        return read_trajectories_csv(self.trial(trial).trajectories())

    def blobs(self, stem: str, camera: str) -> list[Blobs]:
        """The cached blobs of a set of frames of ``camera``, one table per frame."""
        return load_blob_frames(self.blobs_cache(stem, camera))
