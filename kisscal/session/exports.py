"""The calibration for other tools: ``out/cameras.toml`` (anipose, Pose2Sim),
``out/dlt/dltdv.csv`` (DLTdv8), OpenCV YAML files, and ``out/exports.json`` with how
closely each matches kisscal's own cameras; ``kisscal export`` writes one of them alone.

* ``cameras.toml``: OpenCV's model fitted to each camera
  (:func:`kisscal.opencv.opencv_from_camera`) on the rays through the volume the lab
  measures in (:func:`fit_volume`: ``[export] volume_mm`` when given, else the convex
  hull of the control points without the wand's own, :func:`measured_points`, told by
  their ``kind``), or within
  the control points' extent in the image when they span no volume;
  ``exports.json`` gives the fit's RMS and largest distance over the image (px) and the
  DLT's skew, which OpenCV's matrix cannot hold.
* ``dltdv.csv``: the DLT in DLTdv8's pixel convention. DLTdv8 has no lens model: it
  applies the coefficients to pixels as digitised, while kisscal's map to linearised
  pixels; ``exports.json`` gives the size of that difference at the image corners and
  over the image (px), the error DLTdv8 makes where the lens is not corrected.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.camera import Camera
from kisscal.errors import InputError
from kisscal.grid import Linearisation
from kisscal.io.cameras_toml import UNITS_MM, write_cameras_toml, write_opencv_yaml
from kisscal.io.config import SessionConfig
from kisscal.io.dltfiles import DLTDV8_CONVENTION, DltFile, write_dltdv_csv
from kisscal.io.files import write_json
from kisscal.io.store import SessionStore
from kisscal.opencv import OpenCvFit, image_grid, opencv_from_camera
from kisscal.session.calibrated import calibrated_rig, current_rig, read_dlt_files
from kisscal.session.inputs import loads_config
from kisscal.session.progress import Echo, quiet
from kisscal.session.runner import each_camera

#: ``kisscal export --to`` choices.
EXPORT_FORMATS = ("anipose", "pose2sim", "dltdv8", "opencv")


def lens_error_px(camera: Camera) -> dict[str, Any]:
    """How far a tool without a lens model (DLTdv8) puts points: the distance between raw
    and linearised pixels at the four image corners, its largest and RMS value over the
    image (px)."""
    w, h = camera.size_px or (0, 0)
    corners = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [-0.5, h - 0.5], [w - 0.5, h - 0.5]])
    grid = image_grid((w, h))
    at_corners = np.hypot(*(camera.undistort_px(corners) - corners).T)
    over = np.hypot(*(camera.undistort_px(grid) - grid).T)
    return {
        "corners_px": [round(float(d), 4) for d in at_corners],
        "max_px": float(over.max()),
        "rms_px": float(np.sqrt(np.mean(over**2))),
    }


#: The label the wand route gives a wand's image in ``dlt/<camera>.json``: marker, field;
#: what tells them in a file written before control points had a ``kind``.
WAND_LABEL = re.compile(r"W\d+@\d+")

#: Said once when an export tells the wand's images by :data:`WAND_LABEL`.
BY_LABELS = (
    "export: the DLT files' control points have no kind (an older kisscal wrote them): the "
    "wand's images are told by their labels W<marker>@<field>, which a rod named like one "
    "hides; `kisscal calibrate` writes the kinds"
)


def control_xyz(dlt: DltFile | None, rods: Iterable[str] | None = None) -> np.ndarray | None:
    """Lab points (mm) a camera's DLT was fitted to (``points`` of ``dlt/<camera>.json``);
    None when the file lists none. With ``rods`` (the session's rod names), without the
    wand's own images: ``kind`` ``wand``; in a file written before points had a kind,
    labels ``W<marker>@<field>`` (:func:`_wand_image`)."""
    points = (dlt.data or {}).get("points") if dlt is not None else None
    if not points:
        return None
    try:
        if rods is not None:
            points = [p for p in points if not _wand_image(p, rods)]
        xyz = np.array([[p["x_mm"], p["y_mm"], p["z_mm"]] for p in points], dtype=float)
    except (KeyError, TypeError, ValueError, AttributeError):
        return None
    xyz = xyz.reshape(-1, 3)
    return xyz[np.isfinite(xyz).all(axis=1)]


def control_px(camera: Camera, dlt: DltFile | None) -> np.ndarray | None:
    """Raw pixels of the control points a camera's DLT was fitted to, through the
    camera; None when the file lists none."""
    xyz = control_xyz(dlt)
    if xyz is None:
        return None
    uv = camera.project(xyz)
    return uv[np.isfinite(uv).all(axis=1)]


def _wand_image(point: Mapping[str, Any], rods: Iterable[str]) -> bool:
    """Whether a control point is a wand's image: its ``kind`` says, or, without one, its
    label (a rod named ``W1`` labels its markers ``W1@<i>`` too: those are kept)."""
    if "kind" in point:
        return point["kind"] == "wand"
    label = str(point.get("label", ""))
    return WAND_LABEL.fullmatch(label) is not None and label.split("@")[0] not in rods


def told_by_labels(dlts: Mapping[str, DltFile]) -> bool:
    """Whether any camera's control points lack a ``kind`` (:data:`BY_LABELS`)."""
    return any(
        isinstance(p, Mapping) and "kind" not in p
        for d in dlts.values()
        for p in (d.data or {}).get("points") or ()
    )


def control_points(
    dlts: Mapping[str, DltFile], rods: Iterable[str] | None = None
) -> np.ndarray | None:
    """Every camera's control points (lab mm, each once), with ``rods`` without the
    wand's own images (:func:`control_xyz`); None without any."""
    found = [x for x in (control_xyz(d, rods) for d in dlts.values()) if x is not None and len(x)]
    return np.unique(np.concatenate(found), axis=0) if found else None


def measured_points(
    config: SessionConfig, dlts: Mapping[str, DltFile]
) -> tuple[np.ndarray | None, str]:
    """The control points where the lab measures, and what they are: every camera's but
    the wand's own images (``kind`` ``wand``), i.e. the rods' markers, the session's trial
    markers the wand was adjusted with (``trial``), a target's dots, a lab's surveyed
    points; all of them when those span no
    volume (a wand and the axes object alone, or a wand without trials); None without any.

    A wand is waved through a box several times the lab's (on the synthetic webcam rig,
    seed 71, 32 % of its points lie in the volume the rods stand in); the rods and the
    trials' markers are where the lab stood its calibration and its subjects walked."""
    rods = tuple(r.name for r in config.rods.rods) if config.rods else ()
    lab = control_points(dlts, rods)
    if control_volume(lab) is not None:
        return lab, "control points but the wand's images"
    return control_points(dlts), "control points"


@dataclass(frozen=True)
class FitVolume:
    """Where ``cameras.toml``'s cameras are fitted to follow kisscal's (:func:`fit_volume`).

    Attributes
    ----------
    box : tuple of 2 ndarray or None
        The lowest and highest corner (lab mm) of the lattice the fit follows; None: the
        control points' extent in the image instead (they span no volume).
    hull : ndarray or None
        Lab points (mm) whose convex hull keeps the lattice's points; None: all of them.
    by : str
        Where the box came from: ``export.volume_mm``, ``control points but the wand's
        images`` or ``control points``.
    by_labels : bool
        Whether the wand's images were told by their labels (:data:`BY_LABELS`).
    """

    box: tuple[np.ndarray, np.ndarray] | None
    hull: np.ndarray | None
    by: str
    by_labels: bool = False

    def doc(self) -> dict[str, Any]:
        """For ``exports.json``: ``by`` and the box (mm)."""
        box = None if self.box is None else [np.round(c, 1).tolist() for c in self.box]
        return {"by": self.by, "box_mm": box}


def fit_volume(config: SessionConfig, dlts: Mapping[str, DltFile]) -> FitVolume:
    """Where ``cameras.toml``'s cameras are fitted to follow kisscal's: ``[export]
    volume_mm`` when given (its box whole), else :func:`measured_points` (their box,
    within their convex hull)."""
    box = config.export.volume_mm
    if box is not None:
        return FitVolume((np.array(box[0]), np.array(box[1])), None, "export.volume_mm")
    xyz, by = measured_points(config, dlts)
    return FitVolume(control_volume(xyz), xyz, by, told_by_labels(dlts))


def control_volume(xyz: np.ndarray | None) -> tuple[np.ndarray, np.ndarray] | None:
    """The calibrated volume: lowest and highest corner (mm) of the control points
    (:func:`control_points`); None without any, or when they span no volume (fewer than 4
    points, flat)."""
    if xyz is None:
        return None
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    if len(xyz) < 4 or np.any(hi - lo <= 1e-6 * max(float(np.max(hi - lo)), 1.0)):
        return None
    return lo, hi


def _meta(fits: Mapping[str, OpenCvFit]) -> dict[str, Any]:
    """The ``[metadata]`` of a ``cameras.toml`` by table name: how closely each camera
    follows kisscal's (``fit_rms_px``) and where it was fitted to (``fit_region_px``,
    which kisscal's import follows, :func:`kisscal.opencv.camera_from_opencv`)."""
    return {
        "source": "kisscal",
        "fit_rms_px": {name: f.rms_px for name, f in fits.items()},
        "fit_region_px": {
            name: list(f.region_px) for name, f in fits.items() if f.region_px is not None
        },
    }


def _opencv_fits(
    cameras: Iterable[Camera],
    volume: FitVolume,
    dlts: Mapping[str, DltFile],
    pose2sim: bool = False,
    workers: int | None = None,
) -> dict[str, OpenCvFit]:
    """OpenCV's model fitted to each camera over the volume the lab measures in
    (:func:`fit_volume`; for Pose2Sim, which reads ``k1 k2 p1 p2`` only, without ``k3``),
    the cameras side by side in ``workers`` processes (default: one per core; 1: in this
    process): each fit is seconds of Levenberg-Marquardt on its own camera."""
    cameras = list(cameras)
    fit = functools.partial(
        _opencv_fit, dlts=dict(dlts), volume=volume.box, hull=volume.hull, pose2sim=pose2sim
    )
    fits = each_camera(fit, cameras, "export", quiet, workers)
    return {c.id: f for c, f in zip(cameras, fits, strict=True)}


def _opencv_fit(
    camera: Camera,
    echo: Echo,
    dlts: Mapping[str, DltFile],
    volume: tuple[np.ndarray, np.ndarray] | None,
    hull: np.ndarray | None,
    pose2sim: bool,
) -> OpenCvFit:
    """:func:`~kisscal.opencv.opencv_from_camera` of one camera (:func:`_opencv_fits`)."""
    return opencv_from_camera(
        camera,
        coefficients=5 if pose2sim else 12,
        k3=not pose2sim,
        used_px=control_px(camera, dlts.get(camera.id)),
        volume_mm=volume,
        hull_mm=hull,
    )


def write_exports(
    root: Path,
    config: SessionConfig,
    lins: Mapping[str, Linearisation],
    dlts: Mapping[str, DltFile],
    echo: Echo = quiet,
    workers: int | None = None,
) -> dict[str, Any]:
    """Write ``out/dlt/dltdv.csv``, ``out/cameras.toml`` and ``out/exports.json`` for
    every calibrated camera, the cameras' fits in ``workers`` processes (default: one
    per core); returns the content of ``exports.json``."""
    rig = calibrated_rig(config, lins, dlts)
    store = SessionStore(root)
    write_dltdv_csv(store.dltdv_path, {c.id: c.dlt for c in rig})
    cams, volume = [c for c in rig if c.size_px is not None], fit_volume(config, dlts)
    if volume.by_labels:
        echo(BY_LABELS)
    fits = _opencv_fits(cams, volume, dlts, workers=workers)
    report = {
        "cameras_toml": {
            c: {"rms_px": f.rms_px, "max_px": f.max_px, "skew_px": f.skew_px}
            for c, f in fits.items()
        },
        "cameras_toml_volume": volume.doc(),
        "dltdv": {
            "pixel_convention": DLTDV8_CONVENTION,
            "lens_error": {c.id: lens_error_px(c) for c in rig if c.size_px is not None},
        },
    }
    write_cameras_toml(store.cameras_toml_path, [f.camera for f in fits.values()], _meta(fits))
    write_json(store.exports_path, report)
    for cam, f in fits.items():
        lens = report["dltdv"]["lens_error"][cam]
        echo(
            f"  export {cam}: cameras.toml follows kisscal's projection to {f.rms_px:.4f} px "
            f"rms (max {f.max_px:.3f}); dltdv.csv is the plain 11-term DLT, which has no lens "
            f"terms: near the image corners it differs by up to "
            f"{max(lens['corners_px']):.2f} px, the lens distortion kisscal corrects"
        )
    return report


@loads_config
def export(
    root: Path,
    to: str,
    dest: Path | None = None,
    echo: Echo = quiet,
    units: str | None = None,
    *,
    config: SessionConfig,
) -> list[Path]:
    """``kisscal export``: the session's calibration for another tool.

    ``to`` is ``anipose`` (``cameras.toml``), ``pose2sim`` (Pose2Sim's calibration file:
    tables ``cam_01``, ``cam_02``, ... in session order, four distortion coefficients,
    metres), ``dltdv8`` (``dltdv.csv``) or ``opencv`` (one FileStorage YAML per camera);
    ``dest`` is the file (or, for opencv, the folder) to write, by default under ``out/``.
    ``units`` (``mm``, ``cm`` or ``m``) is the length unit of the translations for anipose
    and opencv (default mm, the lab's); Pose2Sim reads metres only.
    """
    if to not in EXPORT_FORMATS:
        raise InputError(f"export: --to must be one of {', '.join(EXPORT_FORMATS)}, got {to!r}")
    units = _export_units(to, units)
    root = Path(root)
    rig = current_rig(root, echo, config=config)
    dlts = read_dlt_files(root, config, required=False)
    store = SessionStore(root)
    if to == "dltdv8":
        path = write_dltdv_csv(dest or store.dltdv_path, {c.id: c.dlt for c in rig})
        echo(f"{path}: {len(rig)} cameras, {DLTDV8_CONVENTION}")
        return [path]
    volume = fit_volume(config, dlts)
    if volume.by_labels:
        echo(BY_LABELS)
    fits = _opencv_fits(rig, volume, dlts, pose2sim=to == "pose2sim")
    for f in fits.values():
        echo(f"  {f.camera.id}: OpenCV model within {f.rms_px:.4f} px rms of kisscal's")
    meta = _meta(fits)
    cams = [f.camera for f in fits.values()]
    if to == "pose2sim":
        # Pose2Sim pairs the calibration's cameras with its pose folders in order,
        # sorted by their last number: cam_01, cam_02, ...
        names = [f"cam_{i + 1:02d}" for i in range(len(cams))]
        # Pose2Sim's own [metadata] keys, then which session camera each table is
        meta = {
            "adjusted": False,
            "error": 0.0,
            "cameras": dict(zip(names, rig.ids, strict=True)),
            **_meta(dict(zip(names, fits.values(), strict=True))),
        }
        path = write_cameras_toml(
            dest or store.pose2sim_path, cams, meta, units="m", names=names, k3=False
        )
        echo(f"{path}: {len(cams)} cameras as {', '.join(names)} (Pose2Sim layout, m)")
        return [path]
    if to == "anipose":
        path = write_cameras_toml(dest or store.cameras_toml_path, cams, meta, units=units)
        echo(f"{path}: {len(cams)} cameras (anipose layout, {units})")
        return [path]
    folder = dest or store.opencv_dir
    paths = [write_opencv_yaml(Path(folder) / f"{c.id}.yml", c, units) for c in cams]
    echo(f"{folder}: {len(paths)} OpenCV camera files ({units})")
    return paths


def _export_units(to: str, units: str | None) -> str:
    """The length unit of an export: ``units`` where the tool takes one, checked."""
    if to == "pose2sim":
        if units not in (None, "m"):
            raise InputError(f"export: Pose2Sim reads metres only; --units {units} is not")
        return "m"
    if units is None:
        return "mm"
    if to == "dltdv8":
        raise InputError("export: --units applies to anipose and opencv; dltdv8 keeps mm")
    if units not in UNITS_MM:
        raise InputError(f"export: --units must be one of {', '.join(UNITS_MM)}, got {units!r}")
    return units
