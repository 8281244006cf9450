"""Synthetic particle frames like the cavity's camera 3, rendered with known centres.

The real frames (``../shared/data/real/openptv-cavity/img_1/cam3.*``, OpenPTV/test_cavity)
were measured once to set the model below; nothing here reads them:

- particle images: a least-squares fit of an elliptical Gaussian to 873 isolated,
  unsaturated targets of OpenPTV's (no other within 8 px) gives peaks of 19 / 82 / 317
  grey levels over the background (5 / 50 / 95 %, log deviation 0.87), deviations along
  x and y of 0.49 / 0.9 / 3 px (10 / 50 / 90 %, log deviation 0.7), elongated (the log
  of their ratio spreads +-0.6, at any angle: short streaks), the fainter ones wider (the
  logs correlate by -0.65: faint diffuse blobs, bright sharp specks); 17 % of the
  targets are saturated (255); 10 % of the targets are streaks (6 px long or more and 2.5
  times longer than wide; particles moving during the exposure): a Gaussian drawn along a
  segment of 3-10 px (:data:`STREAK_SHARE` of the particles, their peak lowered as their
  light spreads: the same summed grey as the spot);
- background: 22 / 35 / 69 grey levels (5 / 50 / 95 %), textured: less its 51 px box
  mean it deviates by 3.34 levels (1.4826 MAD) over the whole frame, but by 1.99 away
  from the lit walls and glare (farther than the box from regions of over 300 px above 9
  levels: 63 % of the frame; 1.77 there between the particles, where it correlates
  with itself by 0.76 / 0.66 / 0.6 / 0.55 / 0.5 / 0.48 at 1 / 2 / 3 / 4 / 6 / 8 px):
  the whole frame's deviation is the lit structure's. Rendered as white noise, a fine
  texture (Gaussian of 1.5 px) and a coarse one (6 px), deviations 0.5 / 0.55 / 0.67 of
  :data:`NOISE` (a rendered frame of seed 1: 2.01 levels, 1.87 between the particles,
  correlations 0.72 / 0.64 / 0.54 / 0.46 / 0.36 / 0.29);
- lit walls (with ``walls``): the cavity's glass edges and glare, bands across the frame
  of 1-12 px (Gaussian deviation), 20-150 levels, their grey varying +-10 % along them;
  with 8 of them a frame of seed 1 deviates by 3.47 levels, 2.08 away from them (65 %
  of the frame), as the real frame does;
- density: 1550-1680 of OpenPTV's targets a frame (1280 x 1024), their nearest neighbour
  closer than 3 / 5 / 6 px for 3.6 / 12 / 19 % of them.

The sizes were then set a little below the fit (its isolated targets are the larger
ones; OpenPTV's targets have 6 / 9 / 15 px, 25 / 50 / 75 %) and the density (a Poisson
field with the faint particles below OpenPTV's threshold) so that OpenPTV's recognition
finds as many targets: on a rendered frame (seed 1, no pairs) 1541 targets, high-passed
peaks 19 / 37 / 66 / 108 / 212 (5 / 25 / 50 / 75 / 95 %; the real 14 / 35 / 74 / 153 /
222), 6.5 % of them long streaks (the real 10 %). Not rendered: the lid's edge and
glare patches (20 % of the real targets kisscal misses stand on the brightest 10 % of
the background), and streaks whose grey rises and falls along them; a real frame's
targets also lie closer (3.6 % within 3 px; here 0.3 %).

Touching pairs are too rare there for a table by distance, so :func:`particle_frame` adds
``pairs`` planted pairs at separations spread over 1-7 px besides the Poisson field.
Centres are in kisscal's pixel convention (the centre of the top-left pixel is 0, 0); each
particle is an elliptical Gaussian integrated over each pixel (4 x 4 samples).

``python -m tests.detect.particle_truth [--seed N] [--pairs N] [--walls N]`` prints the table: for
kisscal's default detection (settings derived from the frame) and OpenPTV's (``optv``, the
cavity's ``targ_rec.par``), the particles found within 1 px, merged and split by the
distance to their nearest neighbour, the extra detections, and how many of the targets
each finds that the other does not are particles.
"""

from __future__ import annotations

import argparse
import itertools
import json
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

#: Particles a square pixel (Poisson field); peak (median, log deviation); size (the
#: geometric mean of the two deviations: median, log deviation, correlation of its log
#: with the peak's, bounds); log deviation of the elongation (long over short deviation).
DENSITY = 1.8e-3
PEAK_MEDIAN, PEAK_LOG_SD = 85.0, 0.9
SIZE_MEDIAN, SIZE_LOG_SD, SIZE_PEAK_CORR, SIZE_BOUNDS = 0.75, 0.6, -0.6, (0.4, 3.0)
ELONGATION_LOG_SD = 0.6
#: Share of the particles drawn as streaks, and their length bounds (px).
STREAK_SHARE, STREAK_PX = 0.25, (3.0, 10.0)
#: Background levels and texture deviation (grey levels): the cavity's away from its lit
#: walls and glare (the whole frame's 3.3 is theirs: render ``walls``).
BACKGROUND, BACKGROUND_SWING, NOISE = 35.0, 20.0, 1.8
#: Background texture: deviations (shares of NOISE) of white noise and of two Gaussian
#: textures, and those textures' deviations (px).
TEXTURE_SHARES, TEXTURE_PX = (0.5, 0.55, 0.67), (1.5, 6.0)
#: Lit walls: deviation across (px), grey levels, variation along them.
WALL_PX, WALL_GREY, WALL_RIPPLE = (1.0, 12.0), (20.0, 150.0), 0.1
#: Half side (px) of the square each particle is rendered in; samples a pixel side.
HALF, SUB = 8, 4


class ParticleFrame(NamedTuple):
    """A rendered frame and its truth: centres (x, y px), peaks, deviations (long, short),
    the long axis's angle (radians), the streak's length along it (px; 0: a spot), and
    the grey the lit walls add to each pixel."""

    image: NDArray[np.uint8]
    xy: NDArray[np.float64]
    peak: NDArray[np.float64]
    sigma: NDArray[np.float64]
    angle: NDArray[np.float64]
    length: NDArray[np.float64]
    wall: NDArray[np.float32]  # grey the lit walls add to each pixel


def _draw(rng: np.random.Generator, n: int) -> tuple[NDArray, ...]:
    """Peaks, deviations (long, short), angles and streak lengths of ``n`` particles."""
    z = rng.standard_normal(n)
    peak = PEAK_MEDIAN * np.exp(PEAK_LOG_SD * z)
    c = SIZE_PEAK_CORR
    size = SIZE_MEDIAN * np.exp(SIZE_LOG_SD * (c * z + np.sqrt(1 - c * c) * rng.standard_normal(n)))
    size = size.clip(*SIZE_BOUNDS)
    stretch = np.exp(np.abs(rng.normal(0.0, ELONGATION_LOG_SD, n)) / 2)
    sigma = np.stack([size * stretch, (size / stretch).clip(SIZE_BOUNDS[0] * 0.8)], 1)
    angle = rng.uniform(0.0, np.pi, n)
    length = np.where(rng.random(n) < STREAK_SHARE, rng.uniform(*STREAK_PX, n), 0.0)
    # a streak spreads the spot's light along its length: the same summed grey
    spread = sigma[:, 0] * np.sqrt(2 * np.pi)
    return peak * spread / (spread + length), sigma, angle, length


def _centres(rng: np.random.Generator, shape: tuple[int, int], pairs: int) -> NDArray:
    """A Poisson field plus ``pairs`` pairs at separations uniform over 1-7 px."""
    h, w = shape
    margin = HALF + 2
    n = rng.poisson(DENSITY * h * w)
    field = rng.uniform((margin, margin), (w - margin, h - margin), (n, 2))
    inner = margin + 7  # the second of a pair stays inside the margin too
    first = rng.uniform((inner, inner), (w - inner, h - inner), (pairs, 2))
    angle = rng.uniform(0, np.pi, pairs)
    gap = rng.uniform(1.0, 7.0, pairs)
    second = first + gap[:, None] * np.stack([np.cos(angle), np.sin(angle)], 1)
    return np.concatenate([field, first, second])


def _texture(rng: np.random.Generator, shape: tuple[int, int], px: float) -> NDArray:
    """Gaussian noise blurred by a Gaussian of ``px``, scaled to unit deviation."""
    import cv2

    field = cv2.GaussianBlur(rng.standard_normal(shape).astype(np.float32), (0, 0), px)
    return field / field.std()


def _background(
    rng: np.random.Generator, shape: tuple[int, int], walls: int
) -> tuple[NDArray, NDArray]:
    """A few long waves around :data:`BACKGROUND` and its texture, and the grey of
    ``walls`` lit walls."""
    yy, xx = np.mgrid[: shape[0], : shape[1]].astype(float)
    out = np.full(shape, BACKGROUND)
    for _ in range(4):
        k = rng.uniform(-1, 1, 2) * 2 * np.pi / 300
        out += BACKGROUND_SWING / 4 * np.sin(k[0] * xx + k[1] * yy + rng.uniform(0, 2 * np.pi))
    white, fine, coarse = (NOISE * share for share in TEXTURE_SHARES)
    out += white * rng.standard_normal(shape)
    out += fine * _texture(rng, shape, TEXTURE_PX[0]) + coarse * _texture(rng, shape, TEXTURE_PX[1])
    ripple = _texture(rng, shape, 4.0) if walls else 0.0
    lit = np.zeros(shape, np.float32)
    for _ in range(walls):  # nearly upright bands, as the cavity's glass edges
        x0, tilt = rng.uniform(50, shape[1] - 50), rng.uniform(-0.05, 0.05)
        width, grey = rng.uniform(*WALL_PX), rng.uniform(*WALL_GREY)
        band = np.exp(-((xx - x0 - tilt * yy) ** 2) / (2 * width**2))
        lit += grey * band * (1 + WALL_RIPPLE * ripple)
    return out, lit


def render(
    shape: tuple[int, int],
    xy: NDArray,
    peak: NDArray,
    sigma: NDArray,
    angle: NDArray,
    length: NDArray,
) -> NDArray:
    """The sum of elliptical Gaussians (``peak``; deviations ``sigma`` long and short, the
    long one at ``angle``) drawn along segments ``length`` long at ``xy``, each pixel the
    mean of SUB x SUB samples."""
    offs = np.arange(-HALF, HALF + 1)
    sub = (np.arange(SUB) + 0.5) / SUB - 0.5
    base = np.floor(xy + 0.5).astype(int)  # the pixel holding each centre
    # sample positions relative to each centre: (n, row, col, sub-row, sub-col)
    dx = (base[:, 0] - xy[:, 0])[:, None, None, None, None] + (offs[:, None] + sub)[
        None, None, :, None, :
    ]
    dy = (base[:, 1] - xy[:, 1])[:, None, None, None, None] + (offs[:, None] + sub)[
        None, :, None, :, None
    ]
    cos, sin = (f(angle)[:, None, None, None, None] for f in (np.cos, np.sin))
    along = dx * cos + dy * sin
    # a streak: flat along its segment, each end falling off as the spot does
    along = np.maximum(np.abs(along) - length[:, None, None, None, None] / 2, 0.0)
    along /= sigma[:, 0, None, None, None, None]
    across = (dy * cos - dx * sin) / sigma[:, 1, None, None, None, None]
    spots = np.exp(-(along**2 + across**2) / 2).mean(axis=(3, 4)) * peak[:, None, None]
    rows = base[:, 1, None, None] + offs[None, :, None]
    cols = base[:, 0, None, None] + offs[None, None, :]
    rows, cols = np.broadcast_arrays(rows, cols)
    flat = np.bincount(
        (rows * shape[1] + cols).ravel(), spots.ravel(), minlength=shape[0] * shape[1]
    )
    return flat.reshape(shape)


def particle_frame(
    seed: int, shape: tuple[int, int] = (1024, 1280), pairs: int = 400, walls: int = 0
) -> ParticleFrame:
    """A cavity-camera-3-like frame of ``shape`` (rows, columns) with ``pairs`` planted
    touching pairs and ``walls`` lit walls, drawn from ``seed``; 8-bit, saturated at 255."""
    rng = np.random.default_rng(seed)
    xy = _centres(rng, shape, pairs)
    peak, sigma, angle, length = _draw(rng, len(xy))
    grey, wall = _background(rng, shape, walls)
    grey += wall + render(shape, xy, peak, sigma, angle, length)
    image = np.clip(np.rint(grey), 0, 255).astype(np.uint8)
    return ParticleFrame(image, xy, peak, sigma, angle, length, wall)


#: Least peak (grey levels) of a particle counted in the truth (6 sensor deviations:
#: fainter ones neither detector is asked to find).
VISIBLE = 20.0
#: Match radius (px) and the nearest-neighbour distance bins (px) of the table.
MATCH_PX = 1.0
BINS = (0.0, 2.0, 3.0, 4.0, 5.0, 7.0, np.inf)
#: A detection within this distance (px) of a particle that has none within MATCH_PX is a
#: piece of it or an offset centroid; a pair's merged centroid lies near their segment.
NEAR_PX = 4.0


def _segment_distance(p: NDArray, a: NDArray, b: NDArray) -> NDArray:
    """Distance of each point ``p`` to the segment from ``a`` to ``b`` (rows paired)."""
    ab = b - a
    t = (((p - a) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-12)).clip(0, 1)
    return np.hypot(*(a + t[:, None] * ab - p).T)


def _streaks(truth: ParticleFrame, found: NDArray) -> dict:
    """Visible streaks with no other particle within 7 px of their ends: how many, the
    share found within 1 px of their middle, and ``split``: two detections or more within
    1.5 px of their segment (one particle read as two)."""
    from scipy.spatial import cKDTree

    xy = truth.xy
    nn = cKDTree(xy).query(xy, k=2)[0][:, 1]
    pick = np.flatnonzero(
        (truth.length > 0) & (truth.peak >= VISIBLE) & (nn >= 7 + truth.length / 2)
    )
    if len(found) == 0 or len(pick) == 0:
        return {"particles": len(pick), "found_pct": None, "split": 0}
    half = (
        truth.length[pick, None]
        / 2
        * np.stack([np.cos(truth.angle[pick]), np.sin(truth.angle[pick])], 1)
    )
    ends = xy[pick] - half, xy[pick] + half
    hit = cKDTree(found).query(xy[pick])[0] <= MATCH_PX
    close = cKDTree(found).query_ball_point(xy[pick], truth.length[pick] / 2 + 1.5)
    pieces = np.array(
        [
            int((_segment_distance(found[c], ends[0][[k]], ends[1][[k]]) <= 1.5).sum())
            for k, c in enumerate(close)
        ]
    )
    return {
        "particles": len(pick),
        "found_pct": round(100 * hit.mean(), 1),
        "split": int((pieces >= 2).sum()),
    }


def score(truth: ParticleFrame, found: NDArray) -> dict:
    """A detector's centres ``found`` against ``truth``, by nearest-neighbour distance.

    For the visible particles (peak at least :data:`VISIBLE`) in each bin of :data:`BINS`
    of the distance to the nearest other visible particle: how many, the share found
    within 1 px, ``merged`` (none within 1 px but one detection within 1 px of the segment
    to the neighbour: one centroid for two) and ``split`` (two detections or more within
    :data:`NEAR_PX` nearer to it than to any particle), and the same for ``streaks``
    alone (:func:`_streaks`). Detections more than 1 px from
    every particle (faint ones too) are ``extra``: ``extra_merged`` (near a pair's
    segment), ``extra_near`` (within :data:`NEAR_PX` of a particle: a piece or an offset
    centroid) or ``extra_false``.
    """
    from scipy.spatial import cKDTree

    xy = truth.xy[truth.peak >= VISIBLE]
    dnn, inn = cKDTree(xy).query(xy, k=2)
    nn, mate = dnn[:, 1], inn[:, 1]
    found = np.asarray(found, float).reshape(-1, 2)
    tree = cKDTree(found) if len(found) else None
    near = tree.query(xy)[0] if tree else np.full(len(xy), np.inf)
    hit = near <= MATCH_PX
    # the detection nearest the pair's midpoint, and its distance to their segment
    mid = (xy + xy[mate]) / 2
    j = tree.query(mid)[1] if tree else np.zeros(len(xy), int)
    seg = _segment_distance(found[j], xy, xy[mate]) if tree else np.full(len(xy), np.inf)
    off = np.minimum(np.hypot(*(found[j] - xy).T), np.hypot(*(found[j] - xy[mate]).T))
    merged = ~hit & (seg <= MATCH_PX) & (off > MATCH_PX)
    owner_d, owner = cKDTree(truth.xy).query(found) if len(found) else (np.zeros(0), [])
    visible_index = np.flatnonzero(truth.peak >= VISIBLE)
    pieces = np.zeros(len(truth.xy), int)
    np.add.at(pieces, np.asarray(owner, int)[owner_d <= NEAR_PX], 1)
    split = pieces[visible_index] >= 2
    rows = []
    for lo, hi in itertools.pairwise(BINS):
        inside = (nn >= lo) & (nn < hi)
        n = int(inside.sum())
        rows.append(
            {
                "nn_px": f"{lo:g}-{hi:g}",
                "particles": n,
                "found_pct": round(100 * hit[inside].mean(), 1) if n else None,
                "merged": int(merged[inside].sum()),
                "split": int(split[inside].sum()),
            }
        )
    extra = owner_d > MATCH_PX
    pairs = cKDTree(truth.xy).query_pairs(7.0, output_type="ndarray")
    on_pair = np.zeros(len(found), bool)
    if len(pairs) and extra.any():
        for a, b in pairs:  # few pairs: a loop in the scoring, not in detection
            on_pair |= _segment_distance(found, truth.xy[a][None], truth.xy[b][None]) <= MATCH_PX
    merged_x = extra & on_pair
    near_x = extra & ~on_pair & (owner_d <= NEAR_PX)
    return {
        "bins": rows,
        "streaks": _streaks(truth, found),
        "visible": len(xy),
        "found_pct": round(100 * hit.mean(), 1),
        "detections": len(found),
        "extra": int(extra.sum()),
        "extra_merged": int(merged_x.sum()),
        "extra_near": int(near_x.sum()),
        "extra_false": int((extra & ~on_pair & ~near_x).sum()),
    }


def openptv_targets(image: NDArray[np.uint8]) -> NDArray[np.float64]:
    """OpenPTV's targets (kisscal's pixels) with the cavity's settings: ``targ_rec.par``
    (grey threshold 9, discontinuity 100, 4-500 px, 2-100 px wide and high, summed grey
    150) after pyptv's 25 px high-pass (``ptv.par`` asks for it)."""
    from optv.image_processing import preprocess_image
    from optv.parameters import ControlParams, TargetParams
    from optv.segmentation import target_recognition

    cpar = ControlParams(1)
    cpar.set_image_size((image.shape[1], image.shape[0]))
    tpar = TargetParams(
        discont=100,
        gvthresh=[9, 9, 9, 9],
        pixel_count_bounds=(4, 500),
        xsize_bounds=(2, 100),
        ysize_bounds=(2, 100),
        min_sum_grey=150,
        cross_size=2,
    )
    found = target_recognition(preprocess_image(image, 0, cpar, 25), tpar, 0, cpar)
    return np.array([t.pos() for t in found], dtype=float).reshape(-1, 2) - 0.5


def _only_in(truth: ParticleFrame, a: NDArray, b: NDArray) -> dict:
    """Centres of ``a`` more than 1 px from every one of ``b``, and how many are particles."""
    from scipy.spatial import cKDTree

    alone = a[cKDTree(b).query(a)[0] > MATCH_PX] if len(b) else a
    true = cKDTree(truth.xy).query(alone)[0] <= MATCH_PX if len(alone) else np.zeros(0, bool)
    return {"only_here": len(alone), "of_them_particles": int(true.sum())}


#: A pixel is on a lit wall where the walls add more than this (grey levels).
LIT = 15.0


def on_walls(truth: ParticleFrame, found: NDArray) -> dict:
    """Visible particles on lit walls and off them (the walls add more than :data:`LIT`)
    and the share found within 1 px; detections on walls and how many of those are more
    than 1 px from every particle."""
    from scipy.spatial import cKDTree

    def lit(xy: NDArray) -> NDArray:
        rows = np.clip(np.rint(xy[:, 1]).astype(int), 0, truth.wall.shape[0] - 1)
        cols = np.clip(np.rint(xy[:, 0]).astype(int), 0, truth.wall.shape[1] - 1)
        return truth.wall[rows, cols] > LIT

    visible = truth.peak >= VISIBLE
    hit = _near(truth.xy, found) <= MATCH_PX
    on, there = lit(truth.xy), lit(found)
    false = cKDTree(truth.xy).query(found)[0] > MATCH_PX
    return {
        "on_walls": int((visible & on).sum()),
        "on_walls_found_pct": round(100 * float(hit[visible & on].mean()), 1),
        "off_walls": int((visible & ~on).sum()),
        "off_walls_found_pct": round(100 * float(hit[visible & ~on].mean()), 1),
        "detections_on_walls": int(there.sum()),
        "false_on_walls": int((there & false).sum()),
        "false_off_walls": int((~there & false).sum()),
    }


def main(argv: list[str] | None = None) -> None:
    from kisscal.detect import detect_blobs
    from kisscal.detect.configure import configure_detection

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--pairs", type=int, default=400)
    parser.add_argument("--walls", type=int, default=0)
    args = parser.parse_args(argv)
    truth = particle_frame(args.seed, pairs=args.pairs, walls=args.walls)
    params = configure_detection([truth.image]).params
    print(json.dumps({"route": params.route, "threshold": params.threshold}))
    ours = detect_blobs(truth.image, params).valid_only().xy_px
    theirs = openptv_targets(truth.image)
    for name, xy, other in (("kisscal", ours, theirs), ("openptv", theirs, ours)):
        result = score(truth, xy)
        for row in result.pop("bins"):
            print(json.dumps({"detector": name, **row}))
        print(json.dumps({"detector": name, "streaks": result.pop("streaks")}))
        print(json.dumps({"detector": name, **result, **_only_in(truth, xy, other)}))
        if args.walls:
            print(json.dumps({"detector": name, **on_walls(truth, xy)}))
    found = float(np.mean(_near(theirs, ours) <= MATCH_PX))
    print(json.dumps({"openptv_targets_kisscal_finds_pct": round(100 * found, 1)}))


def _near(a: NDArray, b: NDArray) -> NDArray:
    from scipy.spatial import cKDTree

    return cKDTree(b).query(a)[0] if len(b) else np.full(len(a), np.inf)


if __name__ == "__main__":
    main()
