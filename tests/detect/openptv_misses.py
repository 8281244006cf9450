"""Why kisscal misses particles tracked through an OpenPTV folder's frames, by cause.

``python -m tests.detect.openptv_misses DIR [CAM ...]`` reads the frames and OpenPTV's
targets of a working folder as :mod:`tests.detect.openptv_heldout` does, derives the
settings per camera as ``kisscal detect`` does, and sorts the particles tracked from
OpenPTV's targets (:func:`~tests.detect.real_acceptance.tracked`) that no valid blob finds
within 1 px by what the "peaks" route did where each one is:

- ``flagged <flags>``: a blob within 1 px, invalid (too small: pixels, extent or summed
  grey under the derived limits);
- ``below threshold``: no pixel of the 3 x 3 around it above the threshold;
- ``centroid 1-2 px off``: the region there has its centroid 1-2 px away (one particle's
  core above the threshold, or a piece of it);
- ``centroid > 2 px off``: the region there is larger (merged with a neighbour, or on
  lit structure) or the particle is cut apart.

One JSON line per camera: the tracked particles, those kisscal finds, the count of each
cause and, for each cause, how many OpenPTV's own targets find within 1 px (when they miss
too, the truth itself is uncertain: a parabola through OpenPTV's centroids).
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from kisscal.detect import DetectionParams, detect_blobs
from kisscal.detect import blobs as fl
from kisscal.detect.configure import configure_detection
from kisscal.detect.peaks import highpass, region_table, regions
from kisscal.io.frames import read_image
from tests.detect.openptv_heldout import _frames, _targets
from tests.detect.real_acceptance import MATCH_PX, tracked


def causes(image: np.ndarray, params: DetectionParams, truth: np.ndarray) -> list[str]:
    """The cause of each missed particle of ``truth`` in ``image`` ("" where found)."""
    blobs = detect_blobs(image, params)
    valid = blobs.valid_only().xy_px
    if len(valid) == 0 or len(truth) == 0:
        return ["below threshold"] * len(truth)
    d_valid = cKDTree(valid).query(truth)[0]
    d_any, nearest = cKDTree(blobs.xy_px).query(truth)
    hp = highpass(image, int(params.peak_highpass_px))
    largest = (params.max_pixels, params.max_width_px, params.max_height_px)
    labels, count = regions(hp, float(params.threshold), largest, float(params.peak_step))
    table = region_table(hp, labels, count, float(params.threshold))
    h, w = labels.shape
    out = []
    for (x, y), dv, da, i in zip(truth, d_valid, d_any, nearest, strict=True):
        if dv <= MATCH_PX:
            out.append("")
            continue
        if da <= MATCH_PX:
            out.append("flagged " + fl.flag_string(int(blobs.flags[i])))
            continue
        c, r = np.rint((x, y)).astype(int)
        around = labels[max(r - 1, 0) : min(r + 2, h), max(c - 1, 0) : min(c + 2, w)]
        if around.max() == 0:
            out.append("below threshold")
            continue
        k = (labels[r, c] if labels[r, c] else around.max()) - 1
        off = np.hypot(table["x"][k] - x, table["y"][k] - y)
        out.append("centroid 1-2 px off" if off <= 2 else "centroid > 2 px off")
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("cams", nargs="*")
    args = parser.parse_args(argv)
    for cam, paths in _frames(args.folder).items():
        if args.cams and cam not in args.cams:
            continue
        images = [read_image(p) for p in paths]
        params = configure_detection(images).params
        if params.route != "peaks":
            print(json.dumps({"camera": cam, "route": params.route}))
            continue
        targets = [_targets(p) for p in paths]
        seen, theirs = Counter(), Counter()
        for k in range(1, len(paths) - 1):
            s = min(max(k - 2, 0), len(paths) - 5)  # five frames: a parabola's motion
            truth = tracked(targets[s : s + 5], k - s)
            if len(truth) == 0:
                continue
            hit = cKDTree(targets[k]).query(truth)[0] <= MATCH_PX
            for cause, ok in zip(causes(images[k], params, truth), hit, strict=True):
                seen[cause or "found"] += 1
                theirs[cause or "found"] += int(ok)
        line = {"camera": cam, "threshold": params.threshold, "tracked": sum(seen.values())}
        for cause, n in seen.most_common():
            line[cause] = n
            line[f"{cause}: openptv finds"] = theirs[cause]
        print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
