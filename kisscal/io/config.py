"""Session configuration: ``session.toml`` (DESIGN.md, "Session on disk", version 1).

:func:`load_session` parses and validates the file into frozen dataclasses. Every error
names the file, the key and what was expected; unknown keys are errors with a
did-you-mean, never silently ignored.
"""

from __future__ import annotations

import difflib
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.errors import KisscalError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib


def load_toml(path: Path) -> dict[str, Any]:
    """Parse a TOML file; a missing or malformed file is a :class:`KisscalError`."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise KisscalError(f"{path}: file not found") from None
    except tomllib.TOMLDecodeError as exc:
        raise KisscalError(f"{path}: not valid TOML ({exc})") from None


@dataclass(frozen=True)
class CameraConfig:
    id: str
    size_px: tuple[int, int]


@dataclass(frozen=True)
class GridConfig:
    rows: int = 15
    cols: int = 20
    images: str = "grid/{camera}/*.png"


@dataclass(frozen=True)
class RodConfig:
    """A calibration rod: surveyed marker centres (n, 3) in mm, top to bottom."""

    name: str
    points_mm: np.ndarray


@dataclass(frozen=True)
class RodsConfig:
    images: str
    rods: tuple[RodConfig, ...]


@dataclass(frozen=True)
class CalibrationConfig:
    """Control points given directly: one CSV per camera (u_px,v_px,x_mm,y_mm,z_mm)."""

    points: str


@dataclass(frozen=True)
class MarkersConfig:
    names: tuple[str, ...]
    template_mm: np.ndarray | None = None
    segments: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class TrialConfig:
    """A trial: exactly one of frame images, a video per camera, or centroid CSVs."""

    name: str
    images: str | None = None
    video: str | None = None
    centroids: str | None = None

    @property
    def source(self) -> str:
        return "images" if self.images else "video" if self.video else "centroids"


@dataclass(frozen=True)
class SessionConfig:
    """A whole ``session.toml``; paths in it are relative to ``root``."""

    root: Path
    name: str
    rate_hz: float
    cameras: tuple[CameraConfig, ...]
    grid: GridConfig | None
    rods: RodsConfig | None
    calibration: CalibrationConfig | None
    detection: dict[str, Any] = field(default_factory=dict)
    markers: MarkersConfig | None = None
    trials: tuple[TrialConfig, ...] = ()
    sections: dict[str, dict[str, Any]] = field(default_factory=dict)

    @property
    def path(self) -> Path:
        return self.root / "session.toml"

    @property
    def camera_ids(self) -> tuple[str, ...]:
        return tuple(c.id for c in self.cameras)

    def trial(self, name: str) -> TrialConfig:
        for t in self.trials:
            if t.name == name:
                return t
        raise KisscalError(
            f"{self.path}: no trial named {name!r}{_suggest(name, [t.name for t in self.trials])}"
            f"; trials: {', '.join(t.name for t in self.trials) or 'none'}"
        )


# Keys each table accepts. Stage sections ([detection], [grid] tuning ...) are checked
# against the stage's parameter dataclass by the session layer.
_TOP = {"session", "cameras", "grid", "rods", "calibration", "detection", "markers", "trials"}
_TOP_OPTIONAL_STAGES = {"dlt", "recon", "tracking"}
_SESSION_KEYS = {"name", "rate_hz"}
_CAMERA_KEYS = {"id", "size"}
_GRID_KEYS = {"rows", "cols", "images"}  # other [grid] keys tune the grid stage (GridParams)
_RODS_KEYS = {"images", "rod"}
_ROD_KEYS = {"name", "points_mm"}
_CALIBRATION_KEYS = {"points"}
_MARKERS_KEYS = {"names", "template_mm", "segments"}
_TRIAL_KEYS = {"name", "images", "video", "centroids"}


def _suggest(key: str, allowed: list[str] | set[str]) -> str:
    close = difflib.get_close_matches(key, sorted(allowed), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _check_keys(path: Path, where: str, table: dict, allowed: set[str]) -> None:
    for key in table:
        if key not in allowed:
            raise KisscalError(
                f"{path}: unknown key {where}{key!r}{_suggest(key, allowed)}; "
                f"expected one of {', '.join(sorted(allowed))}"
            )


def _require(path: Path, where: str, table: dict, key: str) -> Any:
    if key not in table:
        raise KisscalError(f"{path}: missing key {where}{key!r}")
    return table[key]


def _number(path: Path, where: str, value: Any, kind: type = float, positive: bool = True) -> Any:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise KisscalError(f"{path}: {where} must be a number, got {value!r}")
    if kind is int and int(value) != value:
        raise KisscalError(f"{path}: {where} must be a whole number, got {value!r}")
    if positive and value <= 0:
        raise KisscalError(f"{path}: {where} must be positive, got {value!r}")
    return kind(value)


def _string(path: Path, where: str, value: Any) -> str:
    if not isinstance(value, str) or not value:
        raise KisscalError(f"{path}: {where} must be a non-empty string, got {value!r}")
    return value


def _points(path: Path, where: str, value: Any) -> np.ndarray:
    try:
        pts = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise KisscalError(f"{path}: {where} must be a list of [x, y, z] in mm") from None
    if pts.ndim != 2 or pts.shape[1] != 3 or not np.all(np.isfinite(pts)):
        raise KisscalError(
            f"{path}: {where} must be a list of [x, y, z] in mm, got shape {pts.shape}"
        )
    return pts


def parse_session(data: dict[str, Any], root: Path) -> SessionConfig:
    """Validate parsed ``session.toml`` content (paths relative to ``root``)."""
    path = Path(root) / "session.toml"
    _check_keys(path, "", data, _TOP | _TOP_OPTIONAL_STAGES)
    sess = _require(path, "", data, "session")
    _check_keys(path, "session.", sess, _SESSION_KEYS)
    name = _string(path, "session.name", sess.get("name", Path(root).name))
    rate = _number(path, "session.rate_hz", _require(path, "session.", sess, "rate_hz"))

    cams_raw = _require(path, "", data, "cameras")
    if not isinstance(cams_raw, list) or not cams_raw:
        raise KisscalError(f"{path}: [[cameras]] must list at least one camera")
    cameras = []
    for i, c in enumerate(cams_raw):
        _check_keys(path, f"cameras[{i}].", c, _CAMERA_KEYS)
        cid = _string(path, f"cameras[{i}].id", _require(path, f"cameras[{i}].", c, "id"))
        size = _require(path, f"cameras[{i}].", c, "size")
        if not (isinstance(size, list) and len(size) == 2):
            raise KisscalError(f"{path}: cameras[{i}].size must be [width, height] in pixels")
        w = _number(path, f"cameras[{i}].size[0]", size[0], int)
        h = _number(path, f"cameras[{i}].size[1]", size[1], int)
        cameras.append(CameraConfig(cid, (w, h)))
    ids = [c.id for c in cameras]
    if len(set(ids)) != len(ids):
        raise KisscalError(f"{path}: camera ids must be unique, got {', '.join(ids)}")

    grid = None
    if "grid" in data:
        g = data["grid"]
        grid = GridConfig(
            rows=_number(path, "grid.rows", g.get("rows", 15), int),
            cols=_number(path, "grid.cols", g.get("cols", 20), int),
            images=_string(path, "grid.images", g.get("images", GridConfig.images)),
        )

    rods = None
    if "rods" in data:
        r = data["rods"]
        _check_keys(path, "rods.", r, _RODS_KEYS)
        rod_list = []
        for i, rod in enumerate(_require(path, "rods.", r, "rod")):
            _check_keys(path, f"rods.rod[{i}].", rod, _ROD_KEYS)
            rname = _string(
                path, f"rods.rod[{i}].name", _require(path, f"rods.rod[{i}].", rod, "name")
            )
            pts = _points(
                path,
                f"rods.rod[{i}].points_mm",
                _require(path, f"rods.rod[{i}].", rod, "points_mm"),
            )
            rod_list.append(RodConfig(rname, pts))
        _check_control_points(path, "rods.rod", np.concatenate([x.points_mm for x in rod_list]))
        rods = RodsConfig(
            _string(path, "rods.images", _require(path, "rods.", r, "images")), tuple(rod_list)
        )

    calibration = None
    if "calibration" in data:
        c = data["calibration"]
        _check_keys(path, "calibration.", c, _CALIBRATION_KEYS)
        calibration = CalibrationConfig(
            _string(path, "calibration.points", _require(path, "calibration.", c, "points"))
        )

    markers = None
    if "markers" in data:
        m = data["markers"]
        _check_keys(path, "markers.", m, _MARKERS_KEYS)
        names = tuple(
            _string(path, "markers.names[]", n) for n in _require(path, "markers.", m, "names")
        )
        template = None
        if "template_mm" in m:
            template = _points(path, "markers.template_mm", m["template_mm"])
            if len(template) != len(names):
                raise KisscalError(
                    f"{path}: markers.template_mm has {len(template)} positions"
                    f" for {len(names)} names"
                )
        segments = []
        for pair in m.get("segments", []):
            if not (isinstance(pair, list) and len(pair) == 2 and all(p in names for p in pair)):
                raise KisscalError(
                    f"{path}: markers.segments entry {pair!r} must be two marker names"
                )
            segments.append((pair[0], pair[1]))
        markers = MarkersConfig(names, template, tuple(segments))

    trials = []
    for i, t in enumerate(data.get("trials", [])):
        _check_keys(path, f"trials[{i}].", t, _TRIAL_KEYS)
        tname = _string(path, f"trials[{i}].name", _require(path, f"trials[{i}].", t, "name"))
        given = [k for k in ("images", "video", "centroids") if k in t]
        if len(given) != 1:
            raise KisscalError(
                f"{path}: trial {tname!r} needs exactly one of images, video or centroids,"
                f" got {given or 'none'}"
            )
        trials.append(
            TrialConfig(tname, **{given[0]: _string(path, f"trials[{i}].{given[0]}", t[given[0]])})
        )

    detection = data.get("detection", {})
    if not isinstance(detection, dict):
        raise KisscalError(f"{path}: [detection] must be a table")
    return SessionConfig(
        root=Path(root),
        name=name,
        rate_hz=rate,
        cameras=tuple(cameras),
        grid=grid,
        rods=rods,
        calibration=calibration,
        detection=dict(detection),
        markers=markers,
        trials=tuple(trials),
        sections={
            **{k: dict(data[k]) for k in _TOP_OPTIONAL_STAGES if k in data},
            # [grid] keys beyond rows/cols/images are grid-stage parameters, checked
            # (with a did-you-mean) against GridParams by the session layer
            "grid": {k: v for k, v in data.get("grid", {}).items() if k not in _GRID_KEYS},
        },
    )


def _check_control_points(path: Path, where: str, pts: np.ndarray) -> None:
    """A DLT needs at least 6 control points that do not lie in one plane."""
    if len(pts) < 6:
        raise KisscalError(f"{path}: {where} gives {len(pts)} points; the DLT needs at least 6")
    centred = pts - pts.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    if s[2] < 1e-6 * max(s[0], 1e-12) * np.sqrt(len(pts)):
        raise KisscalError(
            f"{path}: {where} points are coplanar; the DLT needs points off one plane"
        )


def load_session(root: Path) -> SessionConfig:
    """Load and validate ``root/session.toml``."""
    root = Path(root)
    if not root.is_dir():
        raise KisscalError(f"{root}: session folder not found")
    return parse_session(load_toml(root / "session.toml"), root)
