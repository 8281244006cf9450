"""Held-out check: default detection on MyPTV's example images against MyPTV's own blobs.

``python -m tests.detect.myptv_heldout MYPTV`` with MYPTV a checkout of github
ronshnapp/MyPTV (MIT) scores kisscal's default detection, settings derived per camera
from the images as ``kisscal detect`` derives them, against the blobs MyPTV's example
found with its own settings (issue 23: real images kisscal was not tuned on):

- the calibration images ``example/Calibration/calN.tif`` against ``camN_CalBlobs``,
  as a grid (``--kind grid``) and as markers (the default kind);
- the particle frames ``example/Images_camN/*.tif`` (the first ``--frames``) against
  ``blobs_camN`` (MyPTV's segmentation: background removed, difference of Gaussians).

MyPTV's blob files give the row, then the column (pixel centres at integers, as
kisscal's). One JSON line per camera and set: references, found by a valid blob within
1 px, split (two blobs or more within the dot radius), valid blobs more than 1 px from
every reference (extra), and the detection's time against OpenCV's threshold and
connected components at the same level (one thread, best of three).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import cv2
import numpy as np

from kisscal.detect import DetectionParams, detect_blobs
from kisscal.detect.background import background_level
from kisscal.detect.configure import configure_detection
from kisscal.io.frames import read_image
from tests.detect.real_acceptance import score_dots


def _blobs(path: Path, frame: int | None = None) -> np.ndarray:
    rows = np.loadtxt(path, ndmin=2)
    if frame is not None:
        rows = rows[rows[:, -1] == frame]
    return rows[:, [1, 0]]


def _times(image: np.ndarray, params: DetectionParams) -> tuple[float, float]:
    """Best of three: kisscal's detection and OpenCV's threshold + components (ms)."""
    level = params.threshold + (background_level(image) if params.background_tile_px else 0.0)

    def opencv() -> None:
        _, white = cv2.threshold(image, level, 255, cv2.THRESH_BINARY)
        cv2.connectedComponentsWithStats(white.astype(np.uint8), connectivity=8)

    best = [np.inf, np.inf]
    for _ in range(3):
        for k, fn in enumerate((lambda: detect_blobs(image, params), opencv)):
            t0 = time.perf_counter()
            fn()
            best[k] = min(best[k], time.perf_counter() - t0)
    return 1000 * best[0], 1000 * best[1]


def _score(name: str, images: list[np.ndarray], refs: list[np.ndarray], kind: str) -> dict:
    params = configure_detection(images, kind=kind).params  # type: ignore[arg-type]
    total = {"references": 0, "found_1px": 0, "split": 0, "valid_blobs": 0, "extra": 0}
    for image, ref in zip(images, refs, strict=True):
        score = score_dots(detect_blobs(image, params), ref, ref)
        total["references"] += score["dots"]
        for key in ("found_1px", "split", "valid_blobs", "extra"):
            total[key] += score[key]
    ms, cv_ms = _times(images[0], params)
    share = 100 * total["found_1px"] / max(total["references"], 1)
    return {
        "set": name,
        "kind": kind,
        "frames": len(images),
        **total,
        "recall_pct": round(share, 1),
        "detect_ms": round(ms),
        "opencv_ms": round(cv_ms),
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("myptv", type=Path)
    parser.add_argument("--frames", type=int, default=5)
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    example = args.myptv / "example"
    for cam in (1, 2, 3):
        cal = example / "Calibration"
        image = read_image(cal / f"cal{cam}.tif")
        dots = _blobs(cal / f"cam{cam}_CalBlobs")
        for kind in ("grid", "markers"):
            print(json.dumps({"camera": cam, **_score("calibration", [image], [dots], kind)}))
        paths = sorted((example / f"Images_cam{cam}").glob("*.tif"))[: args.frames]
        refs = [_blobs(example / f"blobs_cam{cam}", k) for k in range(len(paths))]
        frames = [read_image(p) for p in paths]
        print(json.dumps({"camera": cam, **_score("particles", frames, refs, "markers")}))


if __name__ == "__main__":
    main()
