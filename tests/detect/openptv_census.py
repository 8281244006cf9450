"""Why OpenPTV's targets that kisscal's default detection misses are missed.

``python -m tests.detect.openptv_census [DIR ...]`` takes the cavity's particle frames
(OpenPTV's targets from its own ``target_recognition``, as
:mod:`tests.detect.real_acceptance` finds them; needs ``optv``) and any OpenPTV working
folder given (targets stored beside the frames, as :mod:`tests.detect.openptv_heldout`
reads them), detects with the settings derived per camera, and puts each target without
a valid blob within 1 px in the first class it fits, one JSON line per camera:

- ``two_spots_one_target``: two valid blobs within 4 px with the target within 1 px of the
  segment between them: OpenPTV took two touching spots (a pair of particles) for one
  target, at their common centroid; kisscal separated them. A convention, not a miss.
- ``one_spot_two_targets``: the nearest valid blob (within 4 px) is also the nearest of
  another missed target: OpenPTV cut one spot in two at its grey-level peaks (the two
  lobes of a ring-like particle image, or two particles without a neck between them).
- ``offset_1_4px``: one valid blob 1-4 px away: the two centroid rules differ on this
  spot (extent, weights, background), or a faint tail is counted by one and not the other.
- ``in_oversized``: the nearest blob within 4 px is flagged invalid (part of glare or a lit
  region larger than any object).
- ``below_threshold``: the target's pixel is not white at kisscal's threshold (its local
  background, slack and noise margin are above OpenPTV's flat 9 grey levels over a box
  mean).
- ``no_blob``: white, but in a group removed as noise (one pixel wide or high).
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from kisscal.detect import DetectionParams, detect_blobs
from kisscal.detect.configure import configure_detection
from kisscal.detect.pipeline import threshold_image
from kisscal.io.frames import read_image
from tests.detect.openptv_heldout import _frames, _targets
from tests.detect.real_acceptance import DATA, MATCH_PX, openptv_targets

#: Farthest blob (px) a missed target is put in a class by.
NEAR_PX = 4.0
CLASSES = (
    "two_spots_one_target",
    "one_spot_two_targets",
    "offset_1_4px",
    "in_oversized",
    "below_threshold",
    "no_blob",
)


def _between(t: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each point ``t`` from the segment ``a``-``b`` (rows)."""
    ab = b - a
    s = np.clip(np.sum((t - a) * ab, axis=1) / np.maximum(np.sum(ab * ab, axis=1), 1e-9), 0, 1)
    return np.hypot(*(t - a - s[:, None] * ab).T)


def census(image: np.ndarray, targets: np.ndarray, params: DetectionParams) -> Counter:
    """Targets found within 1 px (``found``) and the class of each missed one."""
    blobs = detect_blobs(image, params)
    valid = blobs.valid_only()
    out = Counter(targets=len(targets))
    if len(targets) == 0 or len(valid) < 2:
        return out
    d, i = cKDTree(valid.xy_px).query(targets, k=2)
    found = d[:, 0] <= MATCH_PX
    out["found"] = int(found.sum())
    miss = ~found
    pair = miss & (d[:, 1] <= NEAR_PX)
    pair &= _between(targets, valid.xy_px[i[:, 0]], valid.xy_px[i[:, 1]]) <= MATCH_PX
    near = miss & ~pair & (d[:, 0] <= NEAR_PX)
    shared = np.bincount(i[near, 0], minlength=len(valid))[i[:, 0]] >= 2
    da, ia = cKDTree(blobs.xy_px).query(targets)
    white, _ = threshold_image(image, params)
    h, w = white.shape
    xi = np.clip(np.rint(targets[:, 0]).astype(int), 0, w - 1)
    yi = np.clip(np.rint(targets[:, 1]).astype(int), 0, h - 1)
    rest = miss & ~pair & ~near
    oversized = rest & (da <= NEAR_PX) & ~blobs.valid[ia]
    dark = rest & ~oversized & ~white[yi, xi]
    masks = (pair, near & shared, near & ~shared, oversized, dark, rest & ~oversized & ~dark)
    for name, mask in zip(CLASSES, masks, strict=True):
        out[name] = int(mask.sum())
    out["extra"] = int((cKDTree(targets).query(valid.xy_px)[0] > MATCH_PX).sum())
    return out


def _line(label: str, total: Counter) -> str:
    n = max(total["targets"], 1)
    row = {"camera": label, "targets": total["targets"], "found_pct": 100 * total["found"] / n}
    row |= {k: 100 * total[k] / n for k in CLASSES}
    row = {k: round(v, 1) if isinstance(v, float) else v for k, v in row.items()}
    return json.dumps(row | {"extra": total["extra"]})


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", type=Path)
    parser.add_argument("--given", type=json.loads, default={}, help="[detection] as JSON")
    parser.add_argument("--no-cavity", action="store_true")
    args = parser.parse_args(argv)
    if (DATA / "img_1").is_dir() and not args.no_cavity:
        for cam in range(4):
            paths = sorted((DATA / "img_1").glob(f"cam{cam + 1}.*"))
            images = [read_image(p) for p in paths]
            params = configure_detection(images, args.given).params
            total: Counter = Counter()
            for image in images:
                targets = openptv_targets(image, cam, DATA)
                if targets is None:
                    print("optv is not installed: no cavity targets")
                    break
                total += census(image, targets, params)
            print(_line(f"cavity cam{cam + 1}", total), flush=True)
    for folder in args.folders:
        for cam, paths in _frames(folder).items():
            images = [read_image(p) for p in paths]
            params = configure_detection(images, args.given).params
            total = Counter()
            for path, image in zip(paths, images, strict=True):
                total += census(image, _targets(path), params)
            print(_line(f"{folder.name} {cam}", total), flush=True)


if __name__ == "__main__":
    main()
