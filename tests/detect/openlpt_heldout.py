"""Held-out check: default detection on a lab's calibration-target images never seen.

``python -m tests.detect.openlpt_heldout OPENLPT [--no-cost]`` with OPENLPT a checkout of
github JHU-NI-LAB/OpenLPT_Shake-The-Box (commit e916093; no licence file, so nothing of
it is copied into this repository) scores kisscal's default detection on the calibration
images of Ni's lab at Johns Hopkins (issue 23: real images kisscal was not tuned on):
``MATLAB/1_Calibration/calib_Ni2017_V3/calib_Ni2017_V3/working/09.28.17 Calibration
Target``, six 1024 x 1024 8-bit frames of six high-speed cameras looking at one back-lit
plate of dark dots (12-25 px wide, 20-55 px apart, seen face-on to strongly obliquely:
ellipses up to twice as tall as wide, some along a diagonal), and the dots the lab's
calibration GUI located in them (``camN.txt``: u, v, then the dot's column and row on
the plate; 133-496 dots a camera, a complete block of the grid). Its pixel convention is
MATLAB's (centre of the top-left pixel at 1, 1): 1 px is subtracted (the median offset
of kisscal's matches is then within 0.4 px).

One JSON line per camera and method: kisscal with the settings ``kisscal detect``
derives (``--kind markers``, the default, and ``--kind grid``, what a user picks for a
target), and OpenCV's SimpleBlobDetector with its default parameters (dark blobs, what
findCirclesGrid runs). For each: the lab's dots found within 1 px, split (two detections
or more within 0.3 dot spacings), extra (detections inside the block of the lab's dots
more than 1 px from every one of them: specks on the plate, mostly), and unless
``--no-cost`` the time of settings + detection (s, one thread, best of three) and the
peak memory of a fresh process that does it (MB, imports included).
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial import Delaunay, cKDTree

from kisscal.detect import detect_blobs
from kisscal.detect.configure import configure_detection
from kisscal.io.frames import read_image
from tests.detect.real_acceptance import MATCH_PX, in_fresh_process, nearest

TARGET = Path(
    "MATLAB/1_Calibration/calib_Ni2017_V3/calib_Ni2017_V3/working/09.28.17 Calibration Target"
)
METHODS = ("markers", "grid", "opencv")


def _detect(image: np.ndarray, method: str) -> np.ndarray:
    """Centres (x, y) of the valid detections of one method."""
    if method == "opencv":
        points = cv2.SimpleBlobDetector_create().detect(image)
        return np.array([k.pt for k in points], float).reshape(-1, 2)
    params = configure_detection([image], kind=method).params  # type: ignore[arg-type]
    return detect_blobs(image, params).valid_only().xy_px


def _score(found: np.ndarray, dots: np.ndarray) -> dict:
    spacing = float(np.median(cKDTree(dots).query(dots, k=2)[0][:, 1]))  # the nearest other
    d, _ = nearest(dots, found)
    pieces = np.zeros(len(dots), int)
    if len(found):
        tree = cKDTree(found)
        pieces = np.asarray(tree.query_ball_point(dots, 0.3 * spacing, return_length=True))
    inside = Delaunay(dots).find_simplex(found) >= 0 if len(found) else np.zeros(0, bool)
    away, _ = nearest(found, dots)
    return {
        "dots": len(dots),
        "found_1px": int((d <= MATCH_PX).sum()),
        "split": int((pieces >= 2).sum()),
        "extra": int((inside & (away > MATCH_PX)).sum()),
        "detections": len(found),
    }


def _cost(path: Path, method: str) -> dict:
    """Time (best of three) and peak memory of ``method`` on ``path``, in a fresh process."""
    return in_fresh_process("tests.detect.openlpt_heldout", ["--cost-of", str(path), method])


def _measure(path: Path, method: str) -> None:
    cv2.setNumThreads(1)
    image = read_image(path)
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        _detect(image, method)
        best = min(best, time.perf_counter() - t0)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(json.dumps({"s": round(best, 2), "peak_mb": round(peak)}))


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("openlpt", type=Path, nargs="?")
    parser.add_argument("--cost-of", nargs=2, metavar=("IMAGE", "METHOD"))
    parser.add_argument("--no-cost", action="store_true")
    args = parser.parse_args(argv)
    if args.cost_of:
        _measure(Path(args.cost_of[0]), args.cost_of[1])
        return
    folder = args.openlpt / TARGET
    for cam in range(1, 7):
        path = next(folder.glob(f"*_C00{cam}H001*.tif"))
        dots = np.loadtxt(folder / f"cam{cam}.txt", delimiter=",", ndmin=2)[:, :2] - 1.0
        image = read_image(path)
        for method in METHODS:
            row = {"camera": cam, "method": method, **_score(_detect(image, method), dots)}
            if not args.no_cost:
                row.update(_cost(path, method))
            print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
