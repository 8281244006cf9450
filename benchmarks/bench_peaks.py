"""Time and memory of the particle route (``route = "peaks"``) on real particle frames.

The cavity experiment's particle frames (``../shared/data/real/openptv-cavity/img_1``,
five per camera, 1280 x 1024 px) and the frames of any OpenPTV folder named in
``KISSCAL_BENCH_PEAK_DIRS`` (folders of ``camN.*`` frames, separated by the path
separator), each camera's frames with the settings ``kisscal detect`` derives from them.
Reference, in the same run on the same frame: OpenCV's threshold at the same level +
``connectedComponentsWithStats`` with its centroids (``bench_real``'s), both on one thread.
Time: this process's CPU time (both run on one thread), best of 3, taken in turns.
Memory: the peak of the arrays allocated during the call (``tracemalloc``; numpy's
arrays, OpenCV's outputs among them). Skipped (one line) when no frames are there.
"""

from __future__ import annotations

import os
import time
import tracemalloc
from pathlib import Path

import cv2
import numpy as np

from benchmarks._harness import best_of_pair
from benchmarks.bench_real import _opencv
from kisscal.detect import detect_blobs
from kisscal.detect.background import background_level
from kisscal.detect.configure import configure_detection
from kisscal.io.frames import read_image
from tests.detect.real_acceptance import DATA


def _folders() -> list[Path]:
    extra = os.environ.get("KISSCAL_BENCH_PEAK_DIRS", "")
    return [DATA / "img_1", *(Path(p) for p in extra.split(os.pathsep) if p)]


def _peak_memory(fn) -> int:
    """Peak bytes of the arrays allocated while ``fn`` runs."""
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _frames(folder: Path) -> list[tuple[str, list]]:
    """(camera, [(path, image)]) of each camera's frames (not OpenPTV's target files)."""
    out = []
    for cam in range(1, 9):
        paths = sorted(
            p for p in folder.glob(f"cam{cam}.*") if p.is_file() and "_targets" not in p.name
        )
        if paths:
            out.append((f"cam{cam}", [(p, read_image(p)) for p in paths]))
    return out


def main() -> list[str]:
    folders = [f for f in _folders() if f.is_dir()]
    if not folders:
        return ["particle frames: skipped, no frames found"]
    previous = cv2.getNumThreads()
    cv2.setNumThreads(1)
    lines, times, memories = [], [], []
    try:
        for folder in folders:
            for _cam, frames in _frames(folder):
                params = configure_detection([im for _, im in frames]).params
                if params.route != "peaks":
                    continue
                for path, image in frames:
                    level = params.threshold
                    if params.background_tile_px:
                        level += background_level(image)
                    ref, ours = best_of_pair(
                        ("opencv", lambda im=image, lv=level: _opencv(im, lv)),
                        ("peaks", lambda im=image, p=params: detect_blobs(im, p)),
                        1,
                        "frames",
                        repeat=3,
                        clock=time.process_time,
                    )
                    mem_ref = _peak_memory(lambda im=image, lv=level: _opencv(im, lv))
                    mem = _peak_memory(lambda im=image, p=params: detect_blobs(im, p))
                    n = len(detect_blobs(image, params))
                    times.append(ours.seconds / ref.seconds)
                    memories.append(mem / mem_ref)
                    lines.append(
                        f"{folder.parent.name}/{folder.name}/{path.name}: {n} blobs, time"
                        f" {1000 * ours.seconds:.1f} ms = {times[-1]:.1f}x opencv, arrays"
                        f" {mem / 2**20:.0f} MB = {memories[-1]:.1f}x opencv"
                    )
    finally:
        cv2.setNumThreads(previous)
    if not times:
        return ["particle frames: none takes the peaks route"]
    lines.append(
        f"particle route / opencv threshold + CC + centroids, 1 thread: time median "
        f"{np.median(times):.1f}x worst {max(times):.1f}x; arrays median "
        f"{np.median(memories):.1f}x worst {max(memories):.1f}x"
    )
    return lines
