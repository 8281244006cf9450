"""Issue 14's figures on a synthetic KISS rig: ``python -m tests.session.interop_acceptance
[SEED]``.

Prints, per camera, how closely ``cv2.projectPoints`` with ``out/cameras.toml`` lands on
kisscal's projection to raw pixels (lab points over the volume that fall in the image)
and the DLTdv corner error; then the 3D distance between the original session's points
and those of the same trial calibrated by each import route.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

from kisscal import session
from kisscal.io.config import load_toml
from kisscal.session.calibrated import current_rig
from tests.session.test_interop import centroid_trial, distances_mm, imported, points3d


def projection_table(root: Path) -> list[str]:
    rig = current_rig(root)
    doc = load_toml(root / "out" / "cameras.toml")
    exports = __import__("json").loads((root / "out" / "exports.json").read_text())
    xyz = np.random.default_rng(0).uniform([-1200, -700, 0], [1200, 700, 2000], (20000, 3))
    lines = [
        "| camera | cv2 vs kisscal rms (px) | max (px) | grid fit rms (px) | skew (px) "
        "| DLTdv corners (px) |",
        "|---|---|---|---|---|---|",
    ]
    for cam in rig:
        c = doc[cam.id]
        uv, _ = cv2.projectPoints(
            xyz.reshape(-1, 1, 3),
            *(np.array(c[k]) for k in ("rotation", "translation", "matrix", "distortions")),
        )
        mine = cam.project(xyz)
        w, h = cam.size_px
        ok = (
            (mine[:, 0] > -0.5)
            & (mine[:, 0] < w - 0.5)
            & (mine[:, 1] > -0.5)
            & (mine[:, 1] < h - 0.5)
        )
        d = np.hypot(*(uv.reshape(-1, 2) - mine)[ok].T)
        fit = exports["cameras_toml"][cam.id]
        corners = exports["dltdv"]["lens_error"][cam.id]["corners_px"]
        lines.append(
            f"| {cam.id} | {np.sqrt(np.mean(d**2)):.4f} | {d.max():.4f} | {fit['rms_px']:.4f} | "
            f"{fit['skew_px']:.4f} | {min(corners):.2f} - {max(corners):.2f} |"
        )
    return lines


def main(seed: int = 3) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        src = session.synthesise(Path(tmp) / "synth", seed=seed, fields=40, walking5=False)
        orig = Path(tmp) / "orig"
        shutil.copytree(src, orig, ignore=shutil.ignore_patterns("out"))
        centroid_trial(orig)
        session.calibrate(orig)
        session.reconstruct(orig, "c2d")
        print(f"KISS rig, seed {seed}")
        print("\n".join(projection_table(orig)))
        routes = {
            "cameras.toml": (
                {"cameras": "cameras.toml"},
                {"cameras.toml": orig / "out" / "cameras.toml"},
                False,
            ),
            "dltdv.csv + grid": (
                {"dlt": "coefs.csv"},
                {"coefs.csv": orig / "out" / "dlt" / "dltdv.csv"},
                True,
            ),
            "dltdv.csv, no grid": (
                {"dlt": "coefs.csv"},
                {"coefs.csv": orig / "out" / "dlt" / "dltdv.csv"},
                False,
            ),
        }
        print(
            "\n| import route | points | median (mm) | 95th pct (mm) | max (mm) |"
            "\n|---|---|---|---|---|"
        )
        for name, (cal, files, grid) in routes.items():
            root = imported(
                orig, Path(tmp) / name.replace(" ", "_").replace(",", ""), cal, files, grid
            )
            d = distances_mm(points3d(orig), points3d(root))
            print(
                f"| {name} | {len(d)} | {np.median(d):.4f} | "
                f"{np.percentile(d, 95):.4f} | {d.max():.4f} |"
            )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
