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

On the "peaks" route (:mod:`kisscal.detect.peaks`, particle frames) the missed targets
are put in the classes of that route instead (:data:`PEAK_CLASSES`, first fit), from the
region of the high-passed image at the target (its pixel or one of its 8 neighbours):

- ``peak_below_threshold``: no region there and the high-passed grey peaks at or below
  the threshold in those 9 pixels (the threshold cut it);
- ``peak_not_grown``: above the threshold but in no region (reached from no peak, or cut
  away when a lit region too large was grown again at a higher level);
- ``peak_merged``: its region holds another target too (OpenPTV cut a spot kisscal kept
  whole: a higher threshold, or its scan-order growth);
- ``peak_border``, ``peak_too_small`` (pixels, summed grey, extent), ``peak_too_large``:
  the region is dropped by the route's limits;
- ``peak_split``: its region is valid, more than 1 px off, and a second valid blob lies
  within 3 px (kisscal cut the spot at two peaks too close for OpenPTV);
- ``peak_offset``: its region is valid but its centroid more than 1 px off (the two
  centroids weigh a different part of the spot: thresholds, high-pass box).

``textured`` is the share of the missed targets (any class) where the local noise
deviation kisscal measures is more than twice the frame's sensor noise: glass walls,
glare and streaks, where kisscal's white test asks for more than a flat grey margin.

With OpenPTV's view of a frame (the cavity; a folder whose experiment's ``parameters``
sit beside it), each *extra* valid blob (more than 1 px from
every target) goes in the first class it fits:

- ``extra_piece``: the nearest target within 4 px has another valid blob within 1 px:
  kisscal found two spots where OpenPTV counts one target.
- ``extra_offset``: the nearest target within 4 px has no blob within 1 px: the same spot,
  the centroids 1-4 px apart (the mirror of the misses' offset and two-spot classes).
- ``extra_faint``: OpenPTV's image (high-passed) peaks below its threshold in the 3 x 3
  pixels at the blob's centroid: a spot too faint for OpenPTV's flat threshold.
- ``extra_small``: fewer than OpenPTV's least pixel count above its threshold, or less
  than its least summed grey, in the 5 x 5 pixels at the centroid (an approximation of
  its region): a spot too small for OpenPTV's target size limits.
- ``extra_lit``: in a lit region of OpenPTV's image (4-connected above its threshold)
  larger than its largest target (``nnmax``, 500 px on the cavity): a wall, glare or the
  lid's edge, which OpenPTV drops whole and kisscal cuts at twice its level, four times,
  ... into particle-sized pieces (particles standing on it, or pieces of the glare).
- ``extra_other``: bright and large enough for OpenPTV, no target within 4 px (joined by
  its region growing to a target farther away, or dropped by its other rules).
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

import cv2
import numpy as np
from scipy.spatial import cKDTree

from kisscal.detect import DetectionParams, detect_blobs
from kisscal.detect import peaks as pk
from kisscal.detect.background import local_background, noise_sigma
from kisscal.detect.configure import configure_detection
from kisscal.detect.pipeline import threshold_image
from kisscal.io.frames import read_image
from tests.detect.openptv_heldout import _frames, _targets
from tests.detect.real_acceptance import DATA, MATCH_PX, OpenptvView, openptv_view

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
PEAK_CLASSES = (
    "peak_below_threshold",
    "peak_not_grown",
    "peak_merged",
    "peak_border",
    "peak_too_small",
    "peak_too_large",
    "peak_split",
    "peak_offset",
)
#: Farthest (px) a second valid blob counts as the other half of a split target.
SPLIT_PX = 3.0
EXTRA_CLASSES = (
    "extra_piece",
    "extra_offset",
    "extra_faint",
    "extra_small",
    "extra_lit",
    "extra_other",
)
#: A stored target is given back by OpenPTV's detection when one lies this close (px), and
#: the detection reads the frame as the stored one did when it gives back this share.
SAME_PX = 0.1
SAME_SHARE = 0.9
#: Local noise over the frame's sensor noise above which a background is textured.
TEXTURED = 2.0


def _between(t: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance of each point ``t`` from the segment ``a``-``b`` (rows)."""
    ab = b - a
    s = np.clip(np.sum((t - a) * ab, axis=1) / np.maximum(np.sum(ab * ab, axis=1), 1e-9), 0, 1)
    return np.hypot(*(t - a - s[:, None] * ab).T)


def census(
    image: np.ndarray,
    targets: np.ndarray,
    params: DetectionParams,
    view: OpenptvView | None = None,
) -> Counter:
    """Targets found within 1 px (``found``), the class of each missed one, how many of
    them lie on a textured background, and with OpenPTV's ``view`` the extras' classes."""
    blobs = detect_blobs(image, params)
    valid = blobs.valid_only()
    out = Counter(targets=len(targets))
    if len(targets) == 0 or len(valid) < 2:
        return out
    d, i = cKDTree(valid.xy_px).query(targets, k=2)
    found = d[:, 0] <= MATCH_PX
    out["found"] = int(found.sum())
    miss = ~found
    out["extra"] = int((cKDTree(targets).query(valid.xy_px)[0] > MATCH_PX).sum())
    if view is not None:
        out += _extras(valid.xy_px, targets, view)
    if params.route == "peaks":
        return out + peak_census(image, targets, params, miss, d[:, 1] <= SPLIT_PX)
    pair = miss & (d[:, 1] <= NEAR_PX)
    pair &= _between(targets, valid.xy_px[i[:, 0]], valid.xy_px[i[:, 1]]) <= MATCH_PX
    near = miss & ~pair & (d[:, 0] <= NEAR_PX)
    shared = np.bincount(i[near, 0], minlength=len(valid))[i[:, 0]] >= 2
    da, ia = cKDTree(blobs.xy_px).query(targets)
    white, _ = threshold_image(image, params)
    xi, yi = _pixel(targets, white.shape)
    rest = miss & ~pair & ~near
    oversized = rest & (da <= NEAR_PX) & ~blobs.valid[ia]
    dark = rest & ~oversized & ~white[yi, xi]
    masks = (pair, near & shared, near & ~shared, oversized, dark, rest & ~oversized & ~dark)
    for name, mask in zip(CLASSES, masks, strict=True):
        out[name] = int(mask.sum())
    noise = local_background(image, params.background_tile_px or 32).noise[yi, xi]
    out["textured"] = int((miss & (noise > TEXTURED * noise_sigma(image))).sum())
    return out


def peak_census(
    image: np.ndarray,
    targets: np.ndarray,
    params: DetectionParams,
    miss: np.ndarray,
    pair: np.ndarray,
) -> Counter:
    """The "peaks" route's class (:data:`PEAK_CLASSES`) of each ``miss``-ed target
    (``pair``: a second valid blob within :data:`SPLIT_PX`)."""
    hp = pk.highpass(image, int(params.peak_highpass_px))
    level = float(params.threshold)
    largest = (params.max_pixels, params.max_width_px, params.max_height_px)
    labels, count = pk.regions(hp, level, largest, float(params.peak_step))
    t = pk.region_table(hp, labels, count, level)
    xi, yi = _pixel(targets, hp.shape)
    lab = np.zeros(len(targets), dtype=np.int64)
    top = np.zeros(len(targets))
    for dy, dx in sorted(np.ndindex(3, 3), key=lambda s: abs(s[0] - 1) + abs(s[1] - 1)):
        y = np.clip(yi + dy - 1, 0, hp.shape[0] - 1)
        x = np.clip(xi + dx - 1, 0, hp.shape[1] - 1)
        lab = np.where(lab == 0, labels[y, x], lab)
        top = np.maximum(top, hp[y, x])
    r = np.maximum(lab - 1, 0)
    small = (t["pixels"] < params.min_pixels) | (t["sum"] < params.peak_min_sum_grey)
    small |= np.minimum(t["w"], t["h"]) < params.peak_min_extent_px
    large = np.zeros(count, dtype=bool)
    for limit, value in zip(largest, (t["pixels"], t["w"], t["h"]), strict=True):
        large |= (value > limit) if limit is not None else False
    shared = np.bincount(lab, minlength=count + 1)[lab] >= 2
    tests = (
        (lab == 0) & (top <= level),
        lab == 0,
        shared,
        t["border"][r],
        small[r],
        large[r],
        pair,
        np.ones(len(targets), dtype=bool),
    )
    out, rest = Counter(), miss.copy()
    for name, test in zip(PEAK_CLASSES, tests, strict=True):
        out[name] = int((rest & test).sum())
        rest &= ~test
    return out


def _pixel(points: np.ndarray, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The pixel (column, row) each point falls in, clipped to the image."""
    xi = np.clip(np.rint(points[:, 0]).astype(int), 0, shape[1] - 1)
    yi = np.clip(np.rint(points[:, 1]).astype(int), 0, shape[0] - 1)
    return xi, yi


def _extras(xy: np.ndarray, targets: np.ndarray, view: OpenptvView) -> Counter:
    """The class of each valid blob (centroids ``xy``) more than 1 px from every target."""
    d, j = cKDTree(targets).query(xy)
    extra = d > MATCH_PX
    to_target, _ = cKDTree(xy).query(targets)
    near = extra & (d <= NEAR_PX)
    piece = near & (to_target[j] <= MATCH_PX)
    offset = near & ~piece
    grey = view.image.astype(np.float32)
    xi, yi = _pixel(xy, grey.shape)
    peak = cv2.dilate(grey, np.ones((3, 3), np.uint8))[yi, xi]
    lit = (grey >= view.threshold).astype(np.float32)
    count = cv2.boxFilter(lit, -1, (5, 5), normalize=False)[yi, xi]
    summed = cv2.boxFilter(grey * lit, -1, (5, 5), normalize=False)[yi, xi]
    rest = extra & ~near
    faint = rest & (peak < view.threshold)
    small = rest & ~faint & ((count < view.min_pixels) | (summed < view.min_sum_grey))
    _, region, stats, _ = cv2.connectedComponentsWithStats(
        (grey > view.threshold).view(np.uint8), connectivity=4
    )
    area = stats[:, cv2.CC_STAT_AREA][region[yi, xi]]
    wall = rest & ~faint & ~small & (region[yi, xi] > 0) & (area > view.max_pixels)
    masks = (piece, offset, faint, small, wall, rest & ~faint & ~small & ~wall)
    return Counter({k: int(m.sum()) for k, m in zip(EXTRA_CLASSES, masks, strict=True)})


def _line(label: str, total: Counter) -> str:
    n = max(total["targets"], 1)
    row = {"camera": label, "targets": total["targets"], "found_pct": 100 * total["found"] / n}
    if any(k in total for k in PEAK_CLASSES):
        row |= {k: total[k] for k in PEAK_CLASSES}
    else:
        row |= {k: 100 * total[k] / n for k in CLASSES}
        row["textured_of_missed_pct"] = 100 * total["textured"] / max(n - total["found"], 1)
    row = {k: round(v, 1) if isinstance(v, float) else v for k, v in row.items()}
    extras = {k: total[k] for k in EXTRA_CLASSES if k in total}
    return json.dumps(row | {"extra": total["extra"]} | extras)


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
                view = openptv_view(image, cam, DATA)
                if view is None:
                    print("optv is not installed: no cavity targets")
                    break
                total += census(image, view.targets, params, view)
            print(_line(f"cavity cam{cam + 1}", total), flush=True)
    for folder in args.folders:
        for cam, paths in _frames(folder).items():
            images = [read_image(p) for p in paths]
            params = configure_detection(images, args.given).params
            total = Counter()
            for path, image in zip(paths, images, strict=True):
                targets = _targets(path)
                total += census(image, targets, params, _stored_view(image, cam, folder, targets))
            print(_line(f"{folder.name} {cam}", total), flush=True)


def _stored_view(
    image: np.ndarray, cam: str, folder: Path, targets: np.ndarray
) -> OpenptvView | None:
    """OpenPTV's view of a working folder's frame, when the experiment's ``parameters``
    sit beside the folder, optv is installed and its detection, high-passed or not (the
    GUI may high-pass whatever ``ptv.par`` says), gives back the stored ``targets``."""
    data = folder.resolve().parent
    if not (data / "parameters" / "targ_rec.par").is_file() or len(targets) == 0:
        return None
    for highpass in (False, True):
        view = openptv_view(image, int(cam.removeprefix("cam")) - 1, data, highpass)
        if view is None or len(view.targets) == 0:
            continue
        if np.mean(cKDTree(view.targets).query(targets)[0] < SAME_PX) >= SAME_SHARE:
            return view._replace(targets=targets)
    return None


if __name__ == "__main__":
    main()
