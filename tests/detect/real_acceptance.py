"""Detection with default settings on real frames, scored against OpenPTV's own results.

``python -m tests.detect.real_acceptance [--data DIR] [--no-cost]`` runs when the real
data of ``../shared/data/real/openptv-cavity`` is there (a lid-driven cavity seen by four
cameras, github OpenPTV/test_cavity, MIT) and prints one JSON line per image:

- calibration images ``cal/camN.tif``: the target dots the camera sees (``camN_dots.csv``,
  41 / 39 / 66 / 67), how many of them kisscal detects as valid blobs within 1 px, how
  many are split (two or more blobs within the dot's radius) and how many were found as
  a split part (cut off a touching speck), and the valid blobs more than 1 px from every
  one of OpenPTV's own detections
  (``camN.tif_targets``): extra detections;
- particle frames ``img_1/camN.1000K``: when OpenPTV's Python bindings are installed
  (``pip install optv``), OpenPTV's targets of that frame, found by its own
  ``target_recognition`` with the experiment's settings (``parameters/targ_rec.par``,
  high-pass as ``ptv.par`` asks), and the fraction of them kisscal finds within 1 px,
  and the same with both at the whole grey level nearest kisscal's derived threshold
  (:func:`at_same_threshold`); otherwise blob counts only; then a line per camera
  scoring both against particles *tracked* through the five frames (:func:`tracked`,
  :func:`tracked_scores`): a truth of the real frames that no threshold or splitting
  convention of the frame scored sets;
- cost (unless ``--no-cost``): peak memory of a fresh process that reads the image,
  derives the settings and detects its blobs, and the time of the detection alone
  against OpenCV's threshold + connected components with statistics and centroids on
  the same frame, both on one thread (best of 5, taken in turns).

Settings are derived as ``kisscal detect`` derives them (:func:`configure_detection`,
default kind): from the image itself for a calibration image, from the camera's five
frames for a particle frame. A closing line sums every camera up.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np
from scipy.spatial import cKDTree

from kisscal.detect import Blobs, DetectionParams, detect_blobs
from kisscal.detect import blobs as fl
from kisscal.detect.background import background_level
from kisscal.detect.configure import configure_detection
from kisscal.io.frames import read_image


def _find_data() -> Path:
    """``shared/data/real/openptv-cavity`` beside the repository (or its parents')."""
    root = Path(__file__).resolve().parents[2]
    for up in (root, *root.parents[:2]):
        here = up.parent / "shared" / "data" / "real" / "openptv-cavity"
        if here.is_dir():
            return here
    return root.parent / "shared" / "data" / "real" / "openptv-cavity"


DATA = _find_data()
#: Match radius (px) of a detection to a reference point.
MATCH_PX = 1.0
#: Blobs within this distance (px) of a dot's centre are pieces of it (dots are ~10 px wide).
DOT_RADIUS_PX = 5.0
SPLIT_FLAGS = fl.SPLIT_UL | fl.SPLIT_UR | fl.SPLIT_WIDE | fl.SPLIT_LONG | fl.SPLIT_TOUCHING


def nearest(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance from each point of ``a`` to the nearest of ``b`` and its index."""
    if len(a) == 0 or len(b) == 0:
        return np.full(len(a), np.inf), np.zeros(len(a), dtype=int)
    d, i = cKDTree(b).query(a)
    return d, i


def score_dots(blobs: Blobs, dots: np.ndarray, reference: np.ndarray) -> dict:
    """Dots found valid within 1 px, dots split, and extra valid blobs (see the module)."""
    valid = blobs.valid_only()
    d, i = nearest(dots, valid.xy_px)
    found = d <= MATCH_PX
    split_part = (valid.flags[i] & SPLIT_FLAGS) != 0 if len(valid) else np.zeros(len(dots), bool)
    pieces = np.zeros(len(dots), dtype=int)
    if len(blobs):
        pieces = np.asarray(
            cKDTree(blobs.xy_px).query_ball_point(dots, DOT_RADIUS_PX, return_length=True)
        )
    # a dot is split when it is cut into two blobs or more (a blob flagged as a split part
    # may be the whole dot, cut off a touching speck: split_part counts those apart)
    split = pieces >= 2
    extra, _ = nearest(valid.xy_px, reference)
    return {
        "dots": len(dots),
        "found_1px": int(found.sum()),
        "recall_pct": round(100 * float(found.mean()), 1) if len(dots) else None,
        "split": int(split.sum()),
        "found_as_split_part": int((found & split_part).sum()),
        "valid_blobs": len(valid),
        "extra": int((extra > MATCH_PX).sum()),
        "reference": len(reference),
    }


def score_targets(blobs: Blobs, targets: np.ndarray) -> dict:
    """OpenPTV's targets found by valid blobs within 1 px, and the valid blobs beyond."""
    valid = blobs.valid_only()
    d, _ = nearest(targets, valid.xy_px)
    extra, _ = nearest(valid.xy_px, targets)
    return {
        "targets": len(targets),
        "found_1px": int((d <= MATCH_PX).sum()),
        "recall_pct": round(100 * float((d <= MATCH_PX).mean()), 1) if len(targets) else None,
        "valid_blobs": len(valid),
        "extra": int((extra > MATCH_PX).sum()),
    }


def openptv_targets(image: np.ndarray, cam: int, data: Path) -> np.ndarray | None:
    """OpenPTV's targets of a frame in kisscal's pixel convention, or None without optv.

    OpenPTV's pixel origin is the corner of the top-left pixel: 0.5 px is subtracted.
    """
    seen = openptv_view(image, cam, data)
    return None if seen is None else seen[0]


class OpenptvView(NamedTuple):
    """OpenPTV's targets of a frame (kisscal's pixels) and how its detection read it."""

    targets: np.ndarray
    image: np.ndarray  # the grey levels it thresholds (high-passed when ptv.par asks)
    threshold: float  # grey level of that image a target's pixels reach (targ_rec.par)
    min_pixels: int  # least pixels of a target
    min_sum_grey: float  # least summed grey of a target
    max_pixels: int = 500  # most pixels of a target (OpenPTV's nnmax; larger: dropped whole)


def openptv_view(
    image: np.ndarray,
    cam: int,
    data: Path,
    highpass: bool | None = None,
    threshold: int | None = None,
) -> OpenptvView | None:
    """OpenPTV's view of a frame (:class:`OpenptvView`), or None without optv; high-passed
    as ``ptv.par`` says unless ``highpass`` says otherwise, at the camera's grey threshold
    of ``targ_rec.par`` unless ``threshold`` is given."""
    try:
        from optv.image_processing import preprocess_image
        from optv.parameters import ControlParams, TargetParams
        from optv.segmentation import target_recognition
    except ImportError:
        return None
    cpar = ControlParams(4)
    cpar.read_control_par(str(data / "parameters" / "ptv.par"))
    tpar = TargetParams()
    tpar.read(str(data / "parameters" / "targ_rec.par"))
    if threshold is not None:
        grey = np.array(tpar.get_grey_thresholds(), dtype=np.int32)
        grey[cam] = threshold
        tpar.set_grey_thresholds(grey)
    if cpar.get_hp_flag() if highpass is None else highpass:
        image = preprocess_image(image, 0, cpar, 25)  # pyptv's high-pass: a 25 px box
    found = target_recognition(image, tpar, cam, cpar)
    targets = np.array([t.pos() for t in found], dtype=float).reshape(-1, 2) - 0.5
    threshold = float(tpar.get_grey_thresholds()[cam])
    least, most = tpar.get_pixel_count_bounds()
    return OpenptvView(targets, image, threshold, least, tpar.get_min_sum_grey(), most)


def at_same_threshold(image: np.ndarray, params: DetectionParams, cam: int, data: Path) -> dict:
    """kisscal and OpenPTV at one grey threshold, the whole level nearest kisscal's derived
    one (kisscal's least summed grey derived from it as ``route.peak_settings`` does;
    OpenPTV's other settings the experiment's): the share of OpenPTV's targets kisscal
    finds within 1 px, and the valid blobs beyond 1 px of every target.

    The experiment's thresholds (9, 9, 9, 11) were set by hand; the share of its targets
    kisscal finds peaks where kisscal's threshold meets the camera's and falls by about
    3 % a grey level either side (below: touching particles merge into one region;
    above: faint ones fall under the size limits or lose their halo). At one threshold
    the share is the detection's own, whatever threshold was chosen.
    """
    level = round(params.threshold)
    same = params.replace(
        threshold=float(level), peak_min_sum_grey=round(params.peak_sum_factor * level, 1)
    )
    scored = score_targets(
        detect_blobs(image, same), openptv_view(image, cam, data, threshold=level).targets
    )
    return {
        "same_threshold": level,
        "same_threshold_targets": scored["targets"],
        "same_threshold_found_1px": scored["found_1px"],
        "same_threshold_pct": scored["recall_pct"],
        "same_threshold_extra": scored["extra"],
    }


#: A tracked particle has no other point this close (px) in the frames it is tracked in.
TRACK_APART_PX = 5.0
#: Farthest (px a frame) a particle moves (the cavity's: 1-2 px, 16 at most), and farthest
#: (px) its point in a frame may lie from the line through two frames' points.
TRACK_REACH_PX = 20.0
TRACK_GATE_PX = 1.5
#: Largest RMS (px) of a track about its parabola in time (centroids: about 0.1 px).
TRACK_RMS_PX = 0.25
#: Least a track moves (px, first frame to last): a spot that stays put (dust, a scratch,
#: a particle stuck on the glass: a fifth of the cavity's tracks move less than 0.5 px
#: in four frames) is no test of finding a moving particle.
TRACK_MOVE_PX = 1.0


def tracked(points: list[np.ndarray], k: int) -> np.ndarray:
    """Positions in frame ``k`` of the particles tracked through every other frame.

    A particle is tracked from the points of the frames before and after ``k``
    (``points``: one (n, 2) array a frame) when it stands alone in each of the other
    frames (:data:`TRACK_APART_PX`), the straight line between those two frames passes
    within :data:`TRACK_GATE_PX` of one of its points in every other frame, the points
    lie on a parabola in time (:data:`TRACK_RMS_PX`), the track moves
    (:data:`TRACK_MOVE_PX`) and is the only one of its points in the two frames; its
    position in frame ``k`` is that parabola's. It is
    a truth for frame ``k`` that neither frame ``k``'s segmentation nor a threshold
    sets: two particles that touch in frame ``k`` and not elsewhere are two tracks.
    Needs a frame before and after ``k``, and four frames besides it (a parabola through
    three points is no test).
    """
    times = np.array([t for t in range(len(points)) if t != k], dtype=float)
    alone = []
    for t in times.astype(int):
        xy = points[t]
        gap = cKDTree(xy).query(xy, 2)[0][:, 1] if len(xy) > 1 else np.full(len(xy), np.inf)
        alone.append(xy[gap > TRACK_APART_PX])
    if min(map(len, alone)) == 0:
        return np.empty((0, 2))
    a = int(np.searchsorted(times, k)) - 1
    span = times[a + 1] - times[a]
    pairs = cKDTree(alone[a]).sparse_distance_matrix(
        cKDTree(alone[a + 1]), TRACK_REACH_PX * span, output_type="coo_matrix"
    )
    i, j = pairs.row, pairs.col
    start, speed = alone[a][i], (alone[a + 1][j] - alone[a][i]) / span
    track = np.empty((i.size, times.size, 2))
    ok = np.ones(i.size, dtype=bool)
    for f, t in enumerate(times):
        d, at = cKDTree(alone[f]).query(start + speed * (t - times[a]))
        ok &= d <= TRACK_GATE_PX
        track[:, f] = alone[f][at]
    powers = np.stack([np.ones_like(times), times, times**2], axis=1)
    fit = np.einsum("ct,ntx->ncx", np.linalg.pinv(powers), track)
    off = np.einsum("tc,ncx->ntx", powers, fit) - track
    ok &= np.sqrt((off**2).sum(axis=2).mean(axis=1)) <= TRACK_RMS_PX
    ok &= np.hypot(*(track[:, -1] - track[:, 0]).T) >= TRACK_MOVE_PX
    i, j, fit = i[ok], j[ok], fit[ok]
    once = (np.bincount(i)[i] == 1) & (np.bincount(j)[j] == 1)  # one track a point
    return np.einsum("c,ncx->nx", np.array([1.0, k, k * k]), fit[once])


#: The two truths of :func:`tracked_scores`.
TRUTHS = ("tracked", "either")


def tracked_scores(found: list[np.ndarray], targets: list[np.ndarray]) -> dict:
    """Particles tracked (:func:`tracked`, over the five frames around each) in every
    frame but the first and last of five or more frames in a row, and how many kisscal
    (``found``: valid blobs a frame) and OpenPTV (``targets``) find within 1 px: tracked
    from OpenPTV's targets (``tracked``: a truth kisscal's detection plays no part in),
    and from either's (``either``: also the faint particles below OpenPTV's limits that
    kisscal follows through the frames)."""
    names = itertools.product(("", "kisscal_", "openptv_"), TRUTHS)
    out = dict.fromkeys((who + on for who, on in names), 0)
    for k in range(1, len(found) - 1):
        s = min(max(k - 2, 0), len(found) - 5)  # five frames: a parabola's motion
        theirs, ours = tracked(targets[s : s + 5], k - s), tracked(found[s : s + 5], k - s)
        either = np.vstack([theirs, ours[nearest(ours, theirs)[0] > MATCH_PX]])
        for on, truth in zip(TRUTHS, (theirs, either), strict=True):
            out[on] += len(truth)
            for who, xy in (("kisscal_", found[k]), ("openptv_", targets[k])):
                out[who + on] += int((nearest(truth, xy)[0] <= MATCH_PX).sum())
    for who, on in itertools.product(("kisscal_", "openptv_"), TRUTHS):
        out[f"{who}{on}_pct"] = round(100 * out[who + on] / max(out[on], 1), 2)
    return out


def _dots(data: Path, cam: int) -> np.ndarray:
    rows = np.loadtxt(data / "cal" / f"cam{cam + 1}_dots.csv", delimiter=",", skiprows=1, ndmin=2)
    return rows[:, 4:6]


def _targets_file(data: Path, cam: int) -> np.ndarray:
    rows = np.loadtxt(data / "cal" / f"cam{cam + 1}.tif_targets", skiprows=1, ndmin=2)
    return rows[:, 1:3] - 0.5


def _settings(paths: list[Path]) -> DetectionParams:
    return configure_detection([read_image(p) for p in paths]).params


def cost(path: Path, sample: list[Path]) -> dict:
    """Peak memory of a fresh process deriving the settings from ``sample`` and detecting
    ``path``, and the detection time against OpenCV's (one thread each)."""
    args = ["--cost-of", str(path)] + [str(p) for p in sample]
    return in_fresh_process("tests.detect.real_acceptance", args)


def in_fresh_process(module: str, args: list[str]) -> dict:
    """The JSON line a fresh ``python -m module args`` prints last (one OpenMP thread), or
    its last error line as ``cost_error``: memory and time measured from nothing."""
    run = subprocess.run(
        [sys.executable, "-m", module, *args],
        capture_output=True,
        text=True,
        cwd=Path(__file__).resolve().parents[2],
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    if run.returncode != 0:
        return {"cost_error": (run.stderr.strip().splitlines() or ["?"])[-1]}
    return json.loads(run.stdout.strip().splitlines()[-1])


def _measure_cost(path: Path, sample: list[Path], given: dict | None = None) -> dict:
    import cv2

    cv2.setNumThreads(1)
    image = read_image(path)
    params = configure_detection([read_image(p) for p in sample], given).params
    blobs = detect_blobs(image, params)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    level = params.threshold
    if params.background_tile_px:  # the same level over the image's median background
        level += background_level(image)

    def opencv() -> None:
        _, white = cv2.threshold(image, level, 255, cv2.THRESH_BINARY)
        cv2.connectedComponentsWithStats(white, connectivity=8)

    best = [np.inf, np.inf]
    for _ in range(5):
        for k, fn in enumerate((lambda: detect_blobs(image, params), opencv)):
            t0 = time.perf_counter()
            fn()
            best[k] = min(best[k], time.perf_counter() - t0)
    return {
        "peak_mb": round(peak_mb),
        "detect_ms": round(1000 * best[0], 1),
        "opencv_ms": round(1000 * best[1], 1),
        "ratio": round(best[0] / best[1], 2),
        "blobs": len(blobs),
    }


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA)
    parser.add_argument("--no-cost", action="store_true", help="skip memory and time")
    parser.add_argument("--cost-of", nargs="+", type=Path, help=argparse.SUPPRESS)
    parser.add_argument(
        "--threshold", type=float, help="with --cost-of: this threshold instead of the derived"
    )
    args = parser.parse_args(argv)
    if args.cost_of:
        given = {} if args.threshold is None else {"threshold": args.threshold}
        sample = args.cost_of[1:] or args.cost_of[:1]
        print(json.dumps(_measure_cost(args.cost_of[0], sample, given)))
        return
    data = args.data
    if not (data / "cal").is_dir():
        print(f"no real data at {data}: nothing to check")
        return
    total = {"dots": 0, "found": 0, "split": 0, "targets": 0, "targets_found": 0}
    total |= {"same_threshold_targets": 0, "same_threshold_found": 0}
    for cam in range(4):
        path = data / "cal" / f"cam{cam + 1}.tif"
        blobs = detect_blobs(read_image(path), _settings([path]))
        line = {"image": str(path.relative_to(data))}
        line.update(score_dots(blobs, _dots(data, cam), _targets_file(data, cam)))
        if not args.no_cost:
            line.update(cost(path, [path]))
        total["dots"] += line["dots"]
        total["found"] += line["found_1px"]
        total["split"] += line["split"]
        print(json.dumps(line), flush=True)
    for cam in range(4):
        frames = sorted((data / "img_1").glob(f"cam{cam + 1}.*"))
        params = _settings(frames)
        seen: list[tuple[np.ndarray, np.ndarray]] = []
        for path in frames:
            image = read_image(path)
            line = {"image": str(path.relative_to(data))}
            targets = openptv_targets(image, cam, data)
            blobs = detect_blobs(image, params)
            if targets is None:
                line.update({"valid_blobs": int(blobs.valid.sum()), "targets": None})
            else:
                seen.append((blobs.valid_only().xy_px, targets))
                line.update(score_targets(blobs, targets))
                total["targets"] += line["targets"]
                total["targets_found"] += line["found_1px"]
                line.update(at_same_threshold(image, params, cam, data))
                total["same_threshold_targets"] += line["same_threshold_targets"]
                total["same_threshold_found"] += line["same_threshold_found_1px"]
            if not args.no_cost:
                line.update(cost(path, frames))
            print(json.dumps(line), flush=True)
        if len(seen) >= 5:  # a frame before and after, four frames to track through
            line = tracked_scores(*(list(x) for x in zip(*seen, strict=True)))
            print(json.dumps({"camera": f"cam{cam + 1}", **line}), flush=True)
            for key in (f"{who}{on}" for who in ("", "kisscal_") for on in TRUTHS):
                total[key] = total.get(key, 0) + line[key]
    print(json.dumps({"summary": total}))


if __name__ == "__main__":
    main()
