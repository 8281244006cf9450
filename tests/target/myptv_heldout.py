"""Held-out check of the known-target route on MyPTV's two example calibrations (issue 23).

``python -m tests.target.myptv_heldout CHECKOUT`` with CHECKOUT a clone of github
ronshnapp/MyPTV (MIT; checked at commit 97f52cf): for ``example`` (three 1280 x 1024
cameras, a 437-point target on several depths) and ``example_fibers`` (three 1024 x
1024 cameras, 480 points), a target session is written from the calibration images,
``target_file`` and the seeds MyPTV's users clicked (``camN_manualPoints``, as they are:
one of them holds a line ``-1 -1`` for a point not clicked), ``kisscal calibrate`` runs
with default settings, and per camera it prints the target points kisscal matched, how
many of the points MyPTV's users matched (``camN_cal_points``) are among them, the model
chosen and the reprojection RMS of kisscal's calibration on MyPTV's matched points.

Measured (2026-12-03): example 431, 428, 423 of 437 points matched (420 of MyPTV's 421,
424 of 432, 407 of 411), 0.37, 0.50, 0.54 px on MyPTV's points, held-out target points
0.059 mm mean (of the calibration as written: 0.058 for the matching's cameras);
example_fibers 480, 479, 480 of 480 (all of MyPTV's but one), 0.11, 0.19, 0.16 px,
0.082 mm (0.083).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from kisscal._shared import rms_px
from kisscal.session.calibrated import current_rig

CAMERAS = ("cam1", "cam2", "cam3")
IMAGES = {"example": "cal{n}.tif", "example_fibers": "cam{n}.tif"}


def write_session(calibration: Path, images: str, root: Path) -> Path:
    """A target session on one MyPTV calibration folder (images linked, files converted)."""
    (root / "cal").mkdir(parents=True)
    xyz = np.loadtxt(calibration / "target_file", ndmin=2)
    lines = ["x_mm,y_mm,z_mm", *(f"{x:g},{y:g},{z:g}" for x, y, z in xyz)]
    (root / "target.csv").write_text("\n".join(lines) + "\n")
    for n, cam in enumerate(CAMERAS, start=1):
        (root / "cal" / f"{cam}.tif").symlink_to(calibration / images.format(n=n))
        seeds = np.loadtxt(calibration / f"{cam}_manualPoints", ndmin=2)
        rows = ["u_px,v_px,x_mm,y_mm,z_mm", *(",".join(f"{a:g}" for a in r) for r in seeds)]
        (root / f"{cam}_seeds.csv").write_text("\n".join(rows) + "\n")
    listed = "".join(f'[[cameras]]\nid = "{c}"\n\n' for c in CAMERAS)
    (root / "session.toml").write_text(
        '[session]\nname = "myptv"\nrate_hz = 100\n\n'
        + listed
        + '[calibration]\ntarget = "target.csv"\nimages = "cal/{camera}.tif"\n'
        + 'seeds = "{camera}_seeds.csv"\n'
    )
    return root


def camera_lines(root: Path, calibration: Path) -> list[str]:
    """One line per camera: matched points, MyPTV's among them, model, RMS on MyPTV's."""
    rig = {c.id: c for c in current_rig(root)}
    doc = json.loads((root / "out" / "dlt" / "target.json").read_text())["cameras"]
    target = np.loadtxt(calibration / "target_file", ndmin=2)
    out = []
    for cam in CAMERAS:
        ref = np.loadtxt(calibration / f"{cam}_cal_points", ndmin=2)
        ids = [np.flatnonzero(np.all(np.isclose(target, p), axis=1))[0] for p in ref[:, 2:5]]
        theirs = int(np.isin(ids, doc[cam]["matched_points"]).sum())
        rms = rms_px(rig[cam].project(ref[:, 2:5]) - ref[:, :2])
        out.append(
            f"  {cam}: {doc[cam]['matched']} of {len(target)} points matched, {theirs} of "
            f"MyPTV's {len(ref)}; model {doc[cam]['model']}; {rms:.3f} px on MyPTV's points"
        )
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkout", type=Path, help="a clone of github ronshnapp/MyPTV")
    args = parser.parse_args(argv)
    failed = 0
    with tempfile.TemporaryDirectory() as tmp:
        for name, images in IMAGES.items():
            calibration = args.checkout.resolve() / name / "Calibration"
            root = write_session(calibration, images, Path(tmp) / name)
            t0 = time.perf_counter()
            run = [sys.executable, "-m", "kisscal", "calibrate", str(root)]
            result = subprocess.run(run, capture_output=True, text=True)
            print(f"{name}: exit {result.returncode} in {time.perf_counter() - t0:.1f} s")
            print("\n".join(line for line in result.stderr.splitlines() if "export" not in line))
            if result.returncode:
                failed += 1
                continue
            print("\n".join(camera_lines(root, calibration)))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
