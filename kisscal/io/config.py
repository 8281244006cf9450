"""Session configuration: ``session.toml`` (DESIGN.md, "Session on disk", versions 1 and 2).

:func:`load_session` parses and validates the file into frozen dataclasses. Every error
names the file, the key and what was expected; unknown keys are errors with a
did-you-mean, never silently ignored. One small parser per table keeps each rule next to
the key it checks.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from kisscal.bundle.params import BundleParams
from kisscal.errors import InputError, KisscalError, MissingDataError
from kisscal.io.toml_table import Table, load_toml, number, suggest, unfilled_keys
from kisscal.markersets import available_marker_sets
from kisscal.markersets import marker_set as pick_markers

#: How interlaced video frames are split into fields (``None``: frames are used whole).
FieldOrder = Literal["top-first", "bottom-first"]
FIELD_ORDERS: tuple[str, ...] = ("top-first", "bottom-first")


@dataclass(frozen=True)
class CameraConfig:
    """A camera: its id and, when given, its image size (width, height) in pixels."""

    id: str
    size_px: tuple[int, int] | None = None


@dataclass(frozen=True)
class GridConfig:
    rows: int = 15
    cols: int = 20
    images: str = "grid/{camera}/*.png"
    fields: FieldOrder | None = None


@dataclass(frozen=True)
class RodConfig:
    """A calibration rod: surveyed marker centres (n, 3) in mm, top to bottom."""

    name: str
    points_mm: np.ndarray


@dataclass(frozen=True)
class RodsConfig:
    images: str
    rods: tuple[RodConfig, ...]
    fields: FieldOrder | None = None


@dataclass(frozen=True)
class CalibrationConfig:
    """A calibration from elsewhere: exactly one route.

    ``points``: control points per camera (CSV ``u_px,v_px,x_mm,y_mm,z_mm``, raw pixels);
    ``cameras``: an anipose / Pose2Sim ``cameras.toml``; ``dlt``: DLTdv coefficients
    (11 rows x one column per camera); ``target`` with ``images`` and ``seeds``: a known
    calibration object matched automatically from a few clicked points per camera.
    ``names`` maps the cameras' names in a ``cameras`` or ``dlt`` file to session camera
    ids (``{"cam_01": "cam1"}``, Pose2Sim's names); unnamed cameras keep their own.
    """

    points: str | None = None
    cameras: str | None = None
    dlt: str | None = None
    target: str | None = None
    images: str | None = None
    seeds: str | None = None
    fields: FieldOrder | None = None
    names: dict[str, str] = dataclasses.field(default_factory=dict)

    @property
    def route(self) -> str:
        """``points``, ``cameras``, ``dlt`` or ``target``."""
        return next(k for k in ("points", "cameras", "dlt", "target") if getattr(self, k))


@dataclass(frozen=True)
class WandConfig:
    """A wand waved through the volume: the trial it is in, its markers along its axis (mm)."""

    trial: str
    markers_mm: tuple[float, ...]


@dataclass(frozen=True)
class AxesConfig:
    """A static object fixing the lab frame: its images and its markers in lab mm."""

    images: str
    points_mm: np.ndarray
    fields: FieldOrder | None = None


@dataclass(frozen=True)
class MarkersConfig:
    """The marker set: a shipped ``set`` and/or names, template and rigid segments."""

    names: tuple[str, ...] = ()
    template_mm: np.ndarray | None = None
    segments: tuple[tuple[str, str], ...] = ()
    set: str | None = None
    static: str | None = None


@dataclass(frozen=True)
class TrialConfig:
    """A trial: exactly one of frame images, a video per camera, centroid CSVs or a C3D."""

    name: str
    images: str | None = None
    video: str | None = None
    centroids: str | None = None
    c3d: str | None = None
    fields: FieldOrder | None = None

    @property
    def source(self) -> str:
        """``images``, ``video``, ``centroids`` or ``c3d``."""
        return next(k for k in TRIAL_SOURCES if getattr(self, k))


TRIAL_SOURCES: tuple[str, ...] = ("images", "video", "centroids", "c3d")


@dataclass(frozen=True)
class ExportConfig:
    """How results are exported: ``trc_up`` is the TRC's vertical axis (OpenSim: y);
    ``volume_mm``, the lowest and highest corner (lab mm) of the volume the lab measures
    in, where ``cameras.toml``'s OpenCV cameras are fitted to follow kisscal's (None: where
    the calibration's rods and trial markers were, :mod:`kisscal.session.exports`)."""

    trc_up: Literal["z", "y"] = "z"
    volume_mm: tuple[tuple[float, ...], tuple[float, ...]] | None = None


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
    wand: WandConfig | None = None
    axes: AxesConfig | None = None
    export: ExportConfig = field(default_factory=ExportConfig)

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
        raise InputError(
            f"{self.path}: no trial named {name!r}{suggest(name, [t.name for t in self.trials])}"
            f"; trials: {', '.join(t.name for t in self.trials) or 'none'}"
        )


# Stage sections whose keys are checked against the stage's parameter dataclass by the
# session layer (with a did-you-mean there).
STAGE_SECTIONS: tuple[str, ...] = (
    "detection",
    "dlt",
    "recon",
    "tracking",
    "gait",
    "report",
    "target",
)
_GRID_KEYS = {"rows", "cols", "images", "fields"}  # other [grid] keys are GridParams
_WAND_KEYS = {"trial", "markers_mm"}  # other [wand] keys are BundleParams


# --------------------------------------------------------------------------- tables


def _session(top: Table, root: Path) -> tuple[str, float]:
    sess = top.sub("session") if "session" in top.data else None
    if sess is None:
        raise top.fail("missing table [session] (name, rate_hz)")
    sess.allow({"name", "rate_hz"})
    return sess.string("name", Path(root).resolve().name) or "", sess.number(
        "rate_hz", sess.required("rate_hz")
    )


def _cameras(top: Table, optional: bool = False) -> tuple[CameraConfig, ...]:
    """``[[cameras]]``; ``optional`` for a session of C3D trials only (its points come
    reconstructed: no camera to name)."""
    tables = top.list_of_tables("cameras")
    if not tables:
        if optional:
            return ()
        raise top.fail("[[cameras]] must list at least one camera")
    cameras = []
    for t in tables:
        t.allow({"id", "size"})
        cid = t.string("id", t.required("id")) or ""
        size = t.data.get("size")
        if size is not None:
            if not (isinstance(size, list) and len(size) == 2):
                raise t.fail(f"{t.where}size must be [width, height] in pixels, got {size!r}")
            size = (
                number(top.path, f"{t.where}size[0]", size[0], int),
                number(top.path, f"{t.where}size[1]", size[1], int),
            )
        cameras.append(CameraConfig(cid, size))
    _unique(top, "camera ids", [c.id for c in cameras])
    return tuple(cameras)


def _unique(t: Table, what: str, names: list[str]) -> None:
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise t.fail(f"{what} must be unique; repeated: {', '.join(repeated)}")


def _grid(t: Table) -> GridConfig:
    return GridConfig(
        rows=t.number("rows", 15, int),
        cols=t.number("cols", 20, int),
        images=t.string("images", GridConfig.images) or GridConfig.images,
        fields=t.choice("fields", FIELD_ORDERS),
    )


def _rods(t: Table) -> RodsConfig:
    t.allow({"images", "rod", "fields"})
    rods = []
    for r in t.list_of_tables("rod"):
        r.allow({"name", "points_mm"})
        rods.append(RodConfig(r.string("name", r.required("name")) or "", r.points("points_mm")))
    if not rods:
        raise t.fail("[rods] needs at least one [[rods.rod]] with name and points_mm")
    _unique(t, "rod names", [r.name for r in rods])
    images = t.string("images", t.required("images")) or ""
    return RodsConfig(images, tuple(rods), t.choice("fields", FIELD_ORDERS))


def _calibration(t: Table) -> CalibrationConfig:
    t.allow({"points", "cameras", "dlt", "target", "images", "seeds", "fields", "names"})
    routes = [k for k in ("points", "cameras", "dlt", "target") if k in t.data]
    if len(routes) != 1:
        raise t.fail(
            "[calibration] needs exactly one of points, cameras, dlt or target, "
            f"got {', '.join(routes) or 'none'}"
        )
    if routes == ["target"]:
        for key in ("images", "seeds"):
            t.required(key)
    else:
        extra = [k for k in ("images", "seeds") if k in t.data]
        if extra:
            raise t.fail(f"calibration.{extra[0]} belongs to a target calibration (target = ...)")
    values = {k: t.string(k) for k in ("points", "cameras", "dlt", "target", "images", "seeds")}
    return CalibrationConfig(
        **values, fields=t.choice("fields", FIELD_ORDERS), names=_camera_names(t, routes[0])
    )


def _camera_names(t: Table, route: str) -> dict[str, str]:
    """``[calibration] names``: foreign camera name -> session camera id, both strings."""
    if "names" not in t.data:
        return {}
    if route not in ("cameras", "dlt"):
        raise t.fail(f"calibration.names renames the cameras of a cameras or dlt file, not {route}")
    names = t.data["names"]
    if not isinstance(names, dict) or not all(
        isinstance(k, str) and isinstance(v, str) and v.strip() for k, v in names.items()
    ):
        raise t.fail('calibration.names must be a table of names, e.g. { cam_01 = "cam1" }')
    ids = list(names.values())
    if len(set(ids)) != len(ids):
        raise t.fail(f"calibration.names maps two names onto one camera: {ids}")
    return dict(names)


def _wand(t: Table) -> WandConfig:
    # keys besides trial and markers_mm tune the wand calibration (BundleParams)
    t.allow(_WAND_KEYS | {f.name for f in dataclasses.fields(BundleParams)})
    trial = t.string("trial", t.required("trial")) or ""
    raw = t.required("markers_mm")
    try:
        markers = np.asarray(raw, dtype=float)
    except (TypeError, ValueError):
        raise t.fail(f"wand.markers_mm must be a list of numbers (mm), got {raw!r}") from None
    if markers.ndim != 1 or len(markers) < 2 or not np.all(np.isfinite(markers)):
        raise t.fail(f"wand.markers_mm must list 2 or more positions in mm, got {raw!r}")
    if np.min(np.diff(np.sort(markers))) <= 0:
        raise t.fail(f"wand.markers_mm positions must be distinct, got {raw!r}")
    return WandConfig(trial, tuple(float(m) for m in markers))


def _axes(t: Table) -> AxesConfig:
    t.allow({"images", "points_mm", "fields"})
    pts = t.points("points_mm")
    if len(pts) < 4:
        raise t.fail(f"axes.points_mm needs 4 or more markers, got {len(pts)}")
    centred = pts - pts.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)
    if s[1] <= 1e-6 * max(s[0], 1e-12):
        raise t.fail("axes.points_mm are collinear; the axes object needs markers off one line")
    return AxesConfig(
        t.string("images", t.required("images")) or "", pts, t.choice("fields", FIELD_ORDERS)
    )


def _markers(t: Table) -> MarkersConfig:
    t.allow({"set", "names", "template_mm", "segments", "static"})
    names = tuple(_string_list(t, "names"))
    marker_set = t.string("set")
    if not names and marker_set is None:
        raise t.fail('[markers] needs names or a set (e.g. set = "plug-in-gait-lower")')
    shipped = available_marker_sets()
    if marker_set is not None and marker_set not in shipped:
        raise t.fail(
            f"markers.set = {marker_set!r} is not a marker set kisscal ships"
            f"{suggest(marker_set, shipped)}; it ships {', '.join(shipped)}"
        )
    if marker_set is not None and names:
        try:
            pick_markers(marker_set, names)
        except KisscalError as exc:
            raise t.fail(f"markers.names: {exc}") from None
    template = t.points("template_mm") if "template_mm" in t.data else None
    if template is not None and len(template) != len(names):
        raise t.fail(f"markers.template_mm has {len(template)} positions for {len(names)} names")
    segments = []
    for pair in t.data.get("segments", []):
        if not (
            isinstance(pair, list) and len(pair) == 2 and all(isinstance(p, str) for p in pair)
        ):
            raise t.fail(f"markers.segments entry {pair!r} must be two marker names")
        unknown = [p for p in pair if names and p not in names]
        if unknown:
            raise t.fail(
                f"markers.segments entry {pair!r}: {unknown[0]!r} is not in markers.names"
                + suggest(unknown[0], names)
            )
        segments.append((pair[0], pair[1]))
    return MarkersConfig(names, template, tuple(segments), marker_set, t.string("static"))


def _string_list(t: Table, key: str) -> list[str]:
    value = t.data.get(key, [])
    if not isinstance(value, list) or not all(isinstance(v, str) and v for v in value):
        raise t.fail(f"{t.where}{key} must be a list of non-empty strings")
    repeated = sorted({v for v in value if value.count(v) > 1})
    if repeated:
        raise t.fail(f"{t.where}{key} repeats {', '.join(repeated)}")
    return value


def _trials(top: Table) -> tuple[TrialConfig, ...]:
    trials = []
    for t in top.list_of_tables("trials"):
        t.allow({"name", *TRIAL_SOURCES, "fields"})
        name = t.string("name", t.required("name")) or ""
        given = [k for k in TRIAL_SOURCES if k in t.data]
        if len(given) != 1:
            raise t.fail(
                f"trial {name!r} needs exactly one of {', '.join(TRIAL_SOURCES)}, "
                f"got {', '.join(given) or 'none'}"
            )
        fields = t.choice("fields", FIELD_ORDERS)
        if fields is not None and given[0] not in ("video", "images"):
            raise t.fail(
                f"trial {name!r}: fields (interlaced field order) applies to images or video only"
            )
        trials.append(TrialConfig(name, **{given[0]: t.string(given[0])}, fields=fields))
    _unique(top, "trial names", [t.name for t in trials])
    return tuple(trials)


def _export(t: Table) -> ExportConfig:
    t.allow({"trc_up", "volume_mm"})
    return ExportConfig(trc_up=t.choice("trc_up", ("z", "y")) or "z", volume_mm=_box(t))


def _box(t: Table) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
    """``export.volume_mm``: two opposite corners (lab mm) as the lowest and highest."""
    if "volume_mm" not in t.data:
        return None
    pts = t.points("volume_mm")
    if len(pts) != 2 or np.any(np.ptp(pts, axis=0) <= 0):
        raise t.fail(
            f"export.volume_mm must be two opposite corners [x, y, z] (mm) differing in x, y "
            f"and z, got {pts.tolist()}"
        )
    return tuple(map(float, pts.min(axis=0))), tuple(map(float, pts.max(axis=0)))


_TABLES: dict[str, Callable[[Table], Any]] = {
    "grid": _grid,
    "rods": _rods,
    "calibration": _calibration,
    "wand": _wand,
    "axes": _axes,
    "markers": _markers,
    "export": _export,
}
_TOP = {"session", "cameras", "trials", *_TABLES, *STAGE_SECTIONS}


def parse_session(data: dict[str, Any], root: Path) -> SessionConfig:
    """Validate parsed ``session.toml`` content (paths relative to ``root``)."""
    top = Table(Path(root) / "session.toml", "", data).allow(_TOP)
    name, rate = _session(top, root)
    parsed = {k: parse(top.sub(k)) for k, parse in _TABLES.items() if k in data}
    sections = {k: dict(top.sub(k).data) for k in STAGE_SECTIONS if k in data}
    # [grid] keys beyond rows/cols/images/fields tune the grid stage (GridParams)
    sections["grid"] = {k: v for k, v in data.get("grid", {}).items() if k not in _GRID_KEYS}
    sections["wand"] = {k: v for k, v in data.get("wand", {}).items() if k not in _WAND_KEYS}
    trials = _trials(top)
    c3d_only = bool(trials) and all(t.source == "c3d" for t in trials)
    calibrates = any(k in data for k in ("grid", "rods", "calibration", "wand"))
    config = SessionConfig(
        root=Path(root),
        name=name,
        rate_hz=rate,
        cameras=_cameras(top, optional=c3d_only and not calibrates),
        grid=parsed.get("grid"),
        rods=parsed.get("rods"),
        calibration=parsed.get("calibration"),
        detection=sections.pop("detection", {}),
        markers=parsed.get("markers"),
        trials=trials,
        sections=sections,
        wand=parsed.get("wand"),
        axes=parsed.get("axes"),
        export=parsed.get("export", ExportConfig()),
    )
    _check_references(top, config)
    return config


def _check_references(top: Table, config: SessionConfig) -> None:
    """Keys that name other parts of the session must name existing ones."""
    trial_names = [t.name for t in config.trials]
    for where, name in (
        ("wand.trial", config.wand.trial if config.wand else None),
        ("markers.static", config.markers.static if config.markers else None),
    ):
        if name is not None and name not in trial_names:
            raise top.fail(
                f"{where} = {name!r} is not a [[trials]] name{suggest(name, trial_names)}"
            )
    if config.calibration is not None and config.rods is not None:
        raise top.fail("give either [rods] or [calibration], not both")
    ids = config.camera_ids
    for name, cam in (config.calibration.names if config.calibration else {}).items():
        if cam not in ids:
            raise top.fail(
                f"calibration.names maps {name!r} to {cam!r}, which is not a camera id"
                f"{suggest(cam, ids)}"
            )
    if config.calibration is not None and config.calibration.cameras and config.grid is not None:
        raise top.fail(
            "[calibration] cameras brings its own lens model; give either it or [grid], not both"
        )


def load_session(root: Path) -> SessionConfig:
    """Load and validate ``root/session.toml``."""
    root = Path(root)
    if not root.is_dir():
        raise MissingDataError(f"{root}: session folder not found")
    data = load_toml(root / "session.toml")
    unfilled = unfilled_keys(data)
    if unfilled:  # a fresh `kisscal init` template: every blank at once, not one per run
        raise InputError(
            f"{root / 'session.toml'}: still to fill in (empty): {', '.join(unfilled)}"
        )
    return parse_session(data, root)
