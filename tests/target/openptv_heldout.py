"""Held-out check of the known-target route on any OpenPTV calibration (issue 23).

``python -m tests.target.openptv_heldout FOLDER --target cal/target.txt [--seeds 4 6]``
with FOLDER an OpenPTV working folder (``cal/camN.tif`` photographs of a target with
their ``.ori`` / ``.addpar`` calibrations, ``parameters/ptv.par`` and
``parameters/detect_plate.par``; needs ``optv``) runs what
:mod:`tests.target.real_acceptance` runs on the cavity, on a lab kisscal was never tuned
on: the target points (``--target``, OpenPTV's ``id x y z`` files; several files, e.g.
the two sides of a two-sided target, are one ``target.csv``) each camera's OpenPTV
calibration projects within 2 px of one of OpenPTV's own detections of the photograph
(``detect_plate.par``) are that camera's reference dots; seeds are picked from them as on
the cavity, ``kisscal calibrate`` runs with default settings and the same table is
printed (matched, RMS on kisscal's and on OpenPTV's dots, OpenPTV's own RMS, a plain DLT).
First, one JSON line per camera scores ``kisscal detect``'s default detection of the
photograph (settings derived from it, default kind) on those reference dots: found by a
valid blob within 1 px, split (two blobs or more within 5 px), time and peak memory are
the CLI's own (``/usr/bin/time -v kisscal detect``).

``--ori DIR`` reads the ``.ori`` / ``.addpar`` files from another folder and ``--ptv-par``
another ``ptv.par`` (a working folder may keep several parameter sets).

Checked on (sources and licences: ``docs/methods.md``, "Held-out target calibrations"):
OpenPTV one-dot-example (a four-view splitter, 6 seeds), jimmy516 OpenPTV_testfolder,
OpenPTV example_calibration_4cam_2side_target (``--target
Particle_motion_4/cal/target_on_a_side1.txt Particle_motion_4/cal/target_on_a_side2.txt
--ori Particle_motion_2/cal``) and OpenPTV example_2cam_90deg (two cameras, ``--target
cal/flat_target.txt``; copy ``parametersRun1/detect_plate.par`` into ``parameters``).
Any number of cameras: ``ptv.par`` says how many.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from kisscal import session
from kisscal.detect import detect_blobs
from kisscal.detect.configure import configure_detection
from kisscal.errors import KisscalError
from kisscal.io.frames import read_image
from tests.detect.real_acceptance import score_dots
from tests.target.cavity import cameras
from tests.target.openptv import project, read_camera
from tests.target.real_acceptance import camera_rows, print_table, write_session

#: Farthest (px) OpenPTV's projection of a target point may lie from its own detection.
REFERENCE_PX = 2.0


def _openptv_dots(image: np.ndarray, folder: Path, ptv_par: Path, cam: int) -> np.ndarray:
    """OpenPTV's detection of a target photograph (``detect_plate.par``), kisscal's pixels."""
    from optv.parameters import ControlParams, TargetParams
    from optv.segmentation import target_recognition

    cpar = ControlParams(4)
    cpar.read_control_par(str(ptv_par))
    tpar = TargetParams()
    tpar.read(str(folder / "parameters" / "detect_plate.par"))
    found = target_recognition(image, tpar, cam, cpar)
    return np.array([t.pos() for t in found], float).reshape(-1, 2) - 0.5


def stage(folder: Path, targets: list[Path], ori: Path, ptv_par: Path, out: Path) -> None:
    """The cavity's layout in ``out`` (see :mod:`tests.target.cavity`) for ``folder``."""
    (out / "cal").mkdir(parents=True)
    (out / "parameters").mkdir()
    shutil.copy(ptv_par, out / "parameters" / "ptv.par")
    xyz = np.concatenate([np.loadtxt(folder / t, ndmin=2)[:, 1:4] for t in targets])
    ids = np.arange(1, len(xyz) + 1)
    table = np.column_stack([ids, xyz])
    np.savetxt(out / "cal" / "target_on_a_side.txt", table, fmt="%d %.6g %.6g %.6g")
    for cam in range(1, int(ptv_par.read_text().split()[0]) + 1):  # ptv.par: cameras first
        name = f"cam{cam}.tif"
        shutil.copy(folder / "cal" / name, out / "cal" / name)
        for ext in (".ori", ".addpar"):
            shutil.copy(ori / (name + ext), out / "cal" / (name + ext))
        camera = read_camera(ori / f"{name}.ori", ori / f"{name}.addpar", ptv_par)
        dots = _openptv_dots(read_image(folder / "cal" / name), folder, ptv_par, cam - 1)
        d, i = cKDTree(dots).query(project(camera, xyz))
        rows = ["id,x_mm,y_mm,z_mm,u_px,v_px"]
        for k in np.flatnonzero(d <= REFERENCE_PX):
            u, v = dots[i[k]]
            rows.append(",".join(f"{a:.6g}" for a in (ids[k], *xyz[k])) + f",{u:.4f},{v:.4f}")
        (out / "cal" / f"cam{cam}_dots.csv").write_text("\n".join(rows) + "\n")


def detection_rows(data: Path) -> list[dict]:
    """Default detection of each staged photograph scored on its reference dots."""
    rows = []
    for cam in cameras(data):
        image = read_image(data / "cal" / f"{cam}.tif")
        table = np.loadtxt(data / "cal" / f"{cam}_dots.csv", delimiter=",", skiprows=1)
        dots = table.reshape(-1, 6)[:, 4:6]
        blobs = detect_blobs(image, configure_detection([image]).params)
        score = score_dots(blobs, dots, dots)
        keep = ("dots", "found_1px", "recall_pct", "split", "valid_blobs")
        rows.append({"camera": cam, **{k: score[k] for k in keep}})
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("--target", type=Path, nargs="+", required=True)
    parser.add_argument("--ori", type=Path, default=None, help="folder of .ori/.addpar")
    parser.add_argument("--ptv-par", type=Path, default=None)
    parser.add_argument("--seeds", type=int, nargs="+", default=[4, 6])
    args = parser.parse_args(argv)
    folder = args.folder
    work = Path(tempfile.mkdtemp(prefix="kisscal-openptv-"))
    data = work / "data"
    ptv_par = args.ptv_par or folder / "parameters" / "ptv.par"
    stage(folder, args.target, args.ori or folder / "cal", ptv_par, data)
    for row in detection_rows(data):
        print(json.dumps(row))
    rows = []
    for n in args.seeds:
        root = write_session(work / f"seeds{n}", data, n)
        said: list[str] = []
        t0 = time.perf_counter()
        try:
            session.calibrate(root, echo=said.append)
        except KisscalError as err:
            print(f"\n{n} seeds per camera: refused: {err}")
            continue
        seconds = time.perf_counter() - t0
        print(f"\n{n} seeds per camera ({seconds:.1f} s):", *said, sep="\n  ")
        rows += camera_rows(root, data, n, seconds)
    if rows:
        print_table(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
