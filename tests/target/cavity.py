"""OpenPTV's cavity calibration target (a real 4-camera rig), for tests and acceptance.

Two sources with the same content: the whole set in ``../shared/data/real/openptv-cavity``
(images, OpenPTV's files; see its README) when it is there, and the small derived files
committed under ``fixtures/real/openptv-cavity`` (``target_*``; see README-target.md
there), which every CI run has.

Each camera's points are the target points OpenPTV's own calibration projects within
2 px of one of its own detections (``camN_dots.csv``: 41 / 39 / 66 / 67 of 73), with that
detection's position in kisscal's pixels.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from tests.target.openptv import OpenPtvCamera, read_camera

REPO = Path(__file__).resolve().parents[2]
FIXTURES = REPO / "fixtures" / "real" / "openptv-cavity"
CAMERAS = ("cam1", "cam2", "cam3", "cam4")
SIZE_PX = (1280, 1024)


def shared_data() -> Path | None:
    """``shared/data/real/openptv-cavity`` beside the repository or a folder above it."""
    for parent in REPO.parents:
        folder = parent / "shared" / "data" / "real" / "openptv-cavity"
        if folder.is_dir():
            return folder
    return None


@dataclass(frozen=True)
class CavityView:
    """The target points one camera sees: id (1-based), lab mm, OpenPTV's detection (px)."""

    camera: str
    ids: NDArray[np.int64]
    xyz_mm: NDArray[np.float64]
    uv_px: NDArray[np.float64]
    openptv: OpenPtvCamera


def cameras(folder: Path) -> tuple[str, ...]:
    """The cameras of a folder with ``cal/camN_dots.csv`` (any number: another lab's rig
    staged by :mod:`tests.target.openptv_heldout`), else the cavity's four."""
    found = sorted(folder.glob("cal/cam*_dots.csv"), key=lambda p: int(p.name[3:-9]))
    return tuple(p.name.removesuffix("_dots.csv") for p in found) or CAMERAS


def target_xyz(folder: Path) -> NDArray[np.float64]:
    """Every target point (73 x 3, mm), row ``i`` is point id ``i + 1``."""
    if (folder / "target_points.csv").is_file():
        rows = list(csv.DictReader((folder / "target_points.csv").open()))
        return np.array([[float(r[k]) for k in ("x_mm", "y_mm", "z_mm")] for r in rows])
    table = np.loadtxt(folder / "cal" / "target_on_a_side.txt")
    return table[np.argsort(table[:, 0]), 1:4]


def view(folder: Path, camera: str) -> CavityView:
    """One camera's points and OpenPTV's calibration of it, from either source."""
    fixture = (folder / f"target_{camera}_dots.csv").is_file()
    dots = folder / (f"target_{camera}_dots.csv" if fixture else f"cal/{camera}_dots.csv")
    ori = folder / (f"target_{camera}.ori" if fixture else f"cal/{camera}.tif.ori")
    addpar = folder / (f"target_{camera}.addpar" if fixture else f"cal/{camera}.tif.addpar")
    ptv = folder / ("target_ptv.par" if fixture else "parameters/ptv.par")
    rows = list(csv.DictReader(dots.open()))
    ids = np.array([int(r["id"]) for r in rows])
    xyz = np.array([[float(r[k]) for k in ("x_mm", "y_mm", "z_mm")] for r in rows])
    uv = np.array([[float(r["u_px"]), float(r["v_px"])] for r in rows])
    return CavityView(camera, ids, xyz, uv, read_camera(ori, addpar, ptv))


def spread_seeds(v: CavityView, n: int) -> NDArray[np.int64]:
    """``n`` points a user would click: spread over the image (farthest first, from the
    top-left), on three different rows of the target when it has them (two rows of this
    target always lie in one plane)."""
    rows = v.xyz_mm[:, 1]
    want_rows = min(3, len(np.unique(rows)), n)
    chosen = [int(np.argmin(v.uv_px.sum(axis=1)))]
    while len(chosen) < n:
        dist = np.min(np.linalg.norm(v.uv_px[:, None] - v.uv_px[chosen][None], axis=2), axis=1)
        have = np.unique(rows[chosen])
        if len(have) < want_rows and n - len(chosen) <= want_rows - len(have):
            dist[np.isin(rows, have)] = -1.0  # the last clicks go to the rows not yet used
        dist[chosen] = -1.0
        chosen.append(int(np.argmax(dist)))
    return np.array(chosen)
