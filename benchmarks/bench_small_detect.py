"""Detection of the small session's frames, one frame at a time and stacked by chunk.

Every image the small session's run detects (:mod:`benchmarks.bench_small`'s cached
default synthetic KISS session: grid, rods and trials, six cameras), with each camera's
session settings (``out/detection/<camera>.json``, derived on first use), in chunks of
:data:`kisscal.detect.sequence.CHUNK_IMAGES` consecutive frames as the detection workers
take them: :func:`kisscal.detect.detect_blobs` on each frame (the per-frame path) against
:func:`kisscal.detect.pipeline.detect_frames` on the chunk (the workers' path), both in
processor time of this one process, as multiples of decoding the same images
(``cv2.imread``) timed in the same run. The frames whose blobs differ between the two
paths are counted (any column not bit-identical, or another flag).

Recorded (2026-11-28, 4044 frames of 752 x 291 px, 2 cores shared with other work, load
about 18): decode 2.46 s; per frame 15.83 s (6.43x decode); grouping steps stacked
(commit a755e38) 10.82 s (4.39x decode, 0.68 of the per-frame time); 0 frames differ.
Every step stacked, cores, splits and moments included (2026-11-29, load about 30):
decode 2.38 s; per frame 15.48 s (6.52x); stacked 4.87 s (2.05x decode, 0.31 of the
per-frame time); 0 frames differ to 1e-9 px; compared bit for bit in a second run:
decode 2.32 s, per frame 15.43 s (6.64x), stacked 4.91 s (2.11x, 0.32), 0 frames differ.
"""

from __future__ import annotations

import os
import time
from collections import defaultdict
from pathlib import Path

import cv2
import numpy as np

from benchmarks.bench_small import _synthesised
from kisscal.detect import Blobs, detect_blobs
from kisscal.detect.pipeline import detect_frames
from kisscal.detect.sequence import CHUNK_IMAGES

COLUMNS = ("x_px", "y_px", "x_binary_px", "y_binary_px", "pixels", "w_px", "h_px", "valid")


def _settings(root: Path) -> dict[tuple[str, str], object]:
    """Each camera's session settings for its grid and marker images."""
    from kisscal.session.inputs import load_config
    from kisscal.session.params import Overrides, stage_params
    from kisscal.session.runner import camera_detection

    config = load_config(root)
    params = stage_params(config, Overrides())
    return {
        (cam.id, kind): camera_detection(config, cam, kind, params)
        for cam in config.cameras
        for kind in ("grid", "markers")
    }


def _differ(a: Blobs, b: Blobs) -> bool:
    if len(a) != len(b) or not np.array_equal(a.flags, b.flags):
        return True
    return any(not np.array_equal(getattr(a, c), getattr(b, c)) for c in COLUMNS)


def main() -> list[str]:
    default = Path.home() / ".cache" / "kisscal" / "bench-small"
    root = _synthesised(Path(os.environ.get("KISSCAL_BENCH_SMALL", default)))
    settings = _settings(root)
    folders: dict[Path, list[Path]] = defaultdict(list)
    for p in sorted(root.rglob("*.png")):
        if p.relative_to(root).parts[0] in ("grid", "rods", "trials"):
            folders[p.parent].append(p)
    spent = {"decode": 0.0, "per frame": 0.0, "stacked": 0.0}
    frames = differ = 0
    for folder, paths in folders.items():
        kind = "grid" if folder.relative_to(root).parts[0] == "grid" else "markers"
        params = settings[(folder.name, kind)]
        for start in range(0, len(paths), CHUNK_IMAGES):
            chunk = paths[start : start + CHUNK_IMAGES]
            t0 = time.process_time()
            images = [cv2.imread(str(p), cv2.IMREAD_UNCHANGED) for p in chunk]
            t1 = time.process_time()
            alone = [detect_blobs(im, params) for im in images]  # type: ignore[arg-type]
            t2 = time.process_time()
            stacked = detect_frames(images, params)  # type: ignore[arg-type]
            t3 = time.process_time()
            spent["decode"] += t1 - t0
            spent["per frame"] += t2 - t1
            spent["stacked"] += t3 - t2
            frames += len(images)
            differ += sum(_differ(a, b) for a, b in zip(alone, stacked, strict=True))
    decode = spent["decode"]
    lines = [f"small session's frames: {frames} images, one process, processor time"]
    for name, seconds in spent.items():
        lines.append(f"  {name:10s} {seconds:7.2f} s  {seconds / decode:5.2f}x decode")
    lines.append(
        f"  stacked / per frame {spent['stacked'] / spent['per frame']:.2f}; "
        f"frames whose blobs differ: {differ}"
    )
    return lines
