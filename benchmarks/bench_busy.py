"""Detection on busy frames: a bright, uneven surround (a lit plate, a saturating lamp, a
ramp) and 1000 dots, 1280 x 1024 (:func:`kisscal.synth.busy.busy_frame`; issue 11).

Reference, timed in the same run on the same frames: ``cv2.threshold`` at kisscal's derived
threshold + ``cv2.connectedComponentsWithStats`` (8-connected) with its centroids, one
thread. At that threshold the plate is one blob of a few hundred thousand pixels, which a
group-level step quadratic in a blob's size would show at once; the frame at twice the size
each way (four times the pixels, 4000 dots) shows how the cost grows. Reported: the
settings kisscal derives (local background or not, threshold), the time ratio to OpenCV
(issue 11 asks for at most 5x), and how many of the true dots each finds within 1 px.

Environment: ``KISSCAL_BENCH_BUSY_SEEDS`` (default 3) frames per size.
"""

from __future__ import annotations

import os

import cv2
import numpy as np
from scipy.spatial import cKDTree

from benchmarks._harness import best_of, report
from kisscal.detect import detect_blobs
from kisscal.detect.configure import configure_detection
from kisscal.synth.busy import busy_frame


def _opencv(image: np.ndarray, threshold: int) -> np.ndarray:
    _, white = cv2.threshold(image, threshold - 1, 1, cv2.THRESH_BINARY)
    _, _, _, centroids = cv2.connectedComponentsWithStats(white, connectivity=8)
    return centroids[1:]


def _found(xy: np.ndarray, centres: np.ndarray) -> int:
    """True dots with a detection within 1 px."""
    if len(xy) == 0:
        return 0
    d, _ = cKDTree(xy).query(centres)
    return int((d < 1.0).sum())


def _size_lines(size_px: tuple[int, int], n_dots: int, n_frames: int) -> list[str]:
    frames = [busy_frame(seed, size_px, n_dots) for seed in range(1, n_frames + 1)]
    images = [f[0] for f in frames]
    setups = [configure_detection([im]) for im in images]
    params = [s.params for s in setups]
    thresholds = [int(p.threshold) for p in params]
    ref = best_of(
        "opencv CC+centroids",
        lambda: [_opencv(im, t) for im, t in zip(images, thresholds, strict=True)],
        n_frames,
        "frames",
    )
    ours = best_of(
        "kisscal detect_blobs (derived settings)",
        lambda: [detect_blobs(im, p) for im, p in zip(images, params, strict=True)],
        n_frames,
        "frames",
    )
    derive = best_of(
        "kisscal configure_detection",
        lambda: [configure_detection([im]) for im in images],
        n_frames,
        "frames",
        repeat=1,
    )
    ocv_found = sum(
        _found(_opencv(im, t), c) for im, t, (_, c) in zip(images, thresholds, frames, strict=True)
    )
    our_found = 0
    for im, p, (_, c) in zip(images, params, frames, strict=True):
        blobs = detect_blobs(im, p).valid_only()
        our_found += _found(np.column_stack([blobs.x_px, blobs.y_px]), c)
    tiles = sorted({p.background_tile_px for p in params})
    total = n_dots * n_frames
    return [
        f"{size_px[0]} x {size_px[1]} px, {n_dots} dots, {n_frames} frames; derived threshold"
        f" {thresholds}, background tile {tiles} px",
        report(ref),
        report(ours, ref),
        f"kisscal configure_detection: {derive.seconds / n_frames:.3f} s per frame (once per"
        " camera in a session)",
        f"dots found within 1 px: kisscal {our_found}/{total}, opencv {ocv_found}/{total}",
    ]


def main() -> list[str]:
    n_frames = int(os.environ.get("KISSCAL_BENCH_BUSY_SEEDS", "3"))
    previous = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        return _size_lines((1280, 1024), 1000, n_frames) + _size_lines((2560, 2048), 4000, n_frames)
    finally:
        cv2.setNumThreads(previous)
