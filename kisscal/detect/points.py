"""Whether a camera images its objects as points, one pixel wide at the threshold.

Shafiq et al. (2001, section 2.2) remove lonely pixels and groups one pixel wide or high
as noise: their markers image as spots several pixels across, and what is that thin at
the threshold is a noise speck that barely crossed it. Particle-tracking cameras (small
tracers far away, a sharp lens) image many objects as points: a particle far brighter
than the threshold may still light a single pixel, or a line of two. The survey
(:mod:`kisscal.detect.survey`) leaves those thin groups out, so the marker population it
sees is only the particles that happen to be large; the noise removal then drops most
of the others (issue 23: 80 % of MyPTV's particles).

The thin groups at the chosen threshold tell which: noise specks at a threshold of five
noise deviations or more seldom reach twice its excess, and defective (hot) pixels sit
at the same place in every frame, as a textured background does (the test needs
:data:`MIN_FRAMES` frames: a single calibration image keeps the removal). Thin groups at
least :data:`POINT_PEAK` times the threshold's excess above the background that move
between the frames are objects; when they are at least :data:`POINT_SHARE` of the
bright moving groups, the camera images its objects as points and the noise removal
would cut them: it is switched off (blob route only).

References
----------
Shafiq, M. S., Tümer, S. T., & Güler, H. C. (2001). Marker detection and trajectory
generation algorithms for a multicamera based gait analysis system. Mechatronics, 11(4).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from kisscal.detect.params import DetectionParams
from kisscal.detect.pipeline import threshold_image

#: A thin group this many times the threshold's excess above the background is lit by an
#: object, not by noise that crossed the threshold.
POINT_PEAK = 2.0
#: Share of the bright moving groups that must be thin for the objects to be points.
POINT_SHARE = 0.25
#: Fewest bright moving thin groups (all frames) that can show it.
MIN_POINTS = 5
#: Largest small end (white pixels) of the surveyed objects for them to go on below the
#: noise removal: a 2 x 2 group, the smallest it keeps.
SMALL_OBJECT_PX = 4
#: Fewest frames that tell moving objects from specks fixed in place (a single image's
#: textured background, as a calibration target's, lights many bright thin groups).
MIN_FRAMES = 3
#: Radius (px) and share of the frames within which a group seen again is at one place.
PLACE_PX = 1.5
PLACE_SHARE = 0.6


def _bright_groups(
    image: NDArray, params: DetectionParams
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Centroids of one frame's groups at least :data:`POINT_PEAK` times the threshold's
    excess above the background, and whether each is thin (one pixel wide or high)."""
    white, background = threshold_image(image, params)
    # the threshold counts from the local background, or is a grey level over one level
    excess = params.threshold - (0.0 if params.background_tile_px else float(background))
    n, labels, stats, centres = cv2.connectedComponentsWithStats(
        white.astype(np.uint8), connectivity=8
    )
    contrast = image.astype(np.float32) - np.asarray(background, dtype=np.float32)
    peak = np.full(n, -np.inf, dtype=np.float32)
    lit = labels > 0
    np.maximum.at(peak, labels[lit], contrast[lit])
    bright = peak >= POINT_PEAK * excess
    bright[0] = False  # the background component
    w, h = stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT]
    return centres[bright], ((w == 1) | (h == 1))[bright]


def _moving(xy: list[NDArray[np.float64]]) -> list[NDArray[np.bool_]]:
    """Per frame, the groups not at a place most frames have a group at (hot pixels,
    fixed reflections, a textured background)."""
    every = np.concatenate(xy)
    if not len(every):
        return [np.ones(0, dtype=bool) for _ in xy]
    count = np.asarray(cKDTree(every).query_ball_point(every, PLACE_PX, return_length=True))
    fixed = np.split(count >= PLACE_SHARE * len(xy), np.cumsum([len(p) for p in xy])[:-1])
    return [~f for f in fixed]


def point_objects(frames: Sequence[NDArray], params: DetectionParams) -> tuple[bool, str]:
    """Whether the objects of ``frames`` image as points at ``params``' threshold, and
    why, in words."""
    if len(frames) < MIN_FRAMES:
        return False, f"{len(frames)} frames: too few to tell moving points from fixed specks"
    found = [_bright_groups(image, params) for image in frames]
    moving = _moving([xy for xy, _ in found])
    thin = sum(int((t & m).sum()) for (_, t), m in zip(found, moving, strict=True))
    total = sum(int(m.sum()) for m in moving)
    share = thin / max(total, 1)
    facts = (
        f"{thin} of {total} moving groups {POINT_PEAK:g} thresholds above the background are "
        f"one pixel wide or high ({share:.0%})"
    )
    if thin >= MIN_POINTS and share >= POINT_SHARE:
        return True, f"{facts}: objects image as points, not noise"
    return False, f"{facts}: thin groups are noise"


def choose_noise_removal(
    choose: Callable[[str, Any, str], Any],
    frames: Sequence[NDArray],
    params: DetectionParams,
    objects: NDArray[np.integer],
) -> None:
    """Switch the blob route's thin-group noise removal and lower size limit off through
    ``choose(name, value, why)`` (which keeps a value the user gave) when the objects
    image as points (:func:`point_objects`); leave them as they are otherwise.

    ``objects`` are the white pixels of the surveyed objects (thin groups left out). Only
    when they reach down to the smallest groups the removal keeps (:data:`SMALL_OBJECT_PX`)
    may the objects go on below it; markers larger than that stand apart from the thin
    specks of a noisy camera, which are noise however bright (Shafiq et al.'s KISS
    cameras). The peaks route's ``min_pixels`` counts high-passed pixels: left alone.
    """
    if params.route != "blobs" or not objects.size:
        return
    smallest = float(np.percentile(objects, 1)) if objects.size >= 50 else float(objects.min())
    if smallest > SMALL_OBJECT_PX:
        return
    points, why = point_objects(frames, params)
    if not points:
        return
    for name in ("remove_lonely", "remove_one_pixel_wide", "remove_one_pixel_high"):
        choose(name, False, why)
    for name in ("noise_min_width_px", "noise_min_height_px", "min_pixels"):
        choose(name, 1, why)
