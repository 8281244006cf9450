"""Dots of a calibration target in a photograph, under uneven light.

The infrared blob detector of :mod:`kisscal.detect` expects bright markers on a dark
field; a photographed dot plate is dark dots on a light plate (or the reverse) lit
unevenly. Each pixel is compared with the mean of its neighbourhood (OpenCV's box
filter, the idea of adaptive thresholding), which follows the light across the plate;
the pixels beyond ``contrast`` form connected components (OpenCV), kept when their size
and fill are a dot's; each dot's centre is the contrast-weighted centroid over its
component grown by two pixels, which takes in the blurred rim.

Example
-------
>>> import numpy as np
>>> image = np.full((60, 80), 200, np.uint8)
>>> yy, xx = np.mgrid[0:60, 0:80]
>>> image[(xx - 30.0) ** 2 + (yy - 20.0) ** 2 <= 16] = 40
>>> np.round(find_dots(image, "dark"), 2).tolist()
[[30.0, 20.0]]
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points
from kisscal.target.params import DEFAULT_PARAMS, TargetParams


def find_dots(
    image: NDArray, polarity: str = "dark", params: TargetParams = DEFAULT_PARAMS
) -> NDArray[np.float64]:
    """Centres (px) of the target's dots in one grey image, shape (n, 2).

    Parameters
    ----------
    image : ndarray, shape (h, w)
        8- or 16-bit grey image (16-bit is scaled to the 8-bit range).
    polarity : {"dark", "bright"}
        Dots darker or lighter than the plate.
    params : TargetParams
        ``window_px``, ``contrast``, size and fill limits.
    """
    img = image.astype(np.float32)
    if image.dtype == np.uint16:
        img *= 255.0 / 65535.0
    mean = cv2.blur(img, (params.window_px, params.window_px))
    contrast = (mean - img) if polarity == "dark" else (img - mean)
    mask = (contrast > params.contrast).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    area = stats[:, cv2.CC_STAT_AREA]
    box = stats[:, cv2.CC_STAT_WIDTH] * stats[:, cv2.CC_STAT_HEIGHT]
    ok = (area >= params.min_area_px) & (area <= params.max_area_px)
    ok &= area >= params.min_fill * box
    ok[0] = False
    grown = cv2.dilate(labels.astype(np.float32), np.ones((5, 5), np.uint8)).astype(np.int64)
    grown = np.where(labels > 0, labels, grown)  # the rim belongs to the dot it surrounds
    keep = ok[grown] & (grown > 0)
    w = np.clip(contrast, 0.0, None)[keep].astype(float)
    lab = grown[keep]
    yy, xx = np.nonzero(keep)
    total = np.bincount(lab, w, n)
    cx = np.bincount(lab, w * xx, n)
    cy = np.bincount(lab, w * yy, n)
    good = ok & (total > 0)
    return np.column_stack([cx[good] / total[good], cy[good] / total[good]])


def seed_offsets_px(dots_px: ArrayLike, points_px: ArrayLike) -> NDArray[np.float64]:
    """Distance (px) from each of ``points_px`` to the nearest dot (inf where none)."""
    dots = as_points(dots_px, 2, "dots_px")
    pts = as_points(points_px, 2, "points_px")
    if not len(dots):
        return np.full(len(pts), np.inf)
    return np.linalg.norm(pts[:, None] - dots[None], axis=2).min(axis=1)


def find_target_dots(
    image: NDArray, seeds_px: ArrayLike, params: TargetParams = DEFAULT_PARAMS
) -> NDArray[np.float64]:
    """Dots of the polarity ``params.dots``; ``auto``: the one the clicked seeds lie on.

    The seeds lie on the polarity whose dots are nearest them: each seed's distance to
    its nearest dot, at most half the window (a dot is smaller than the window, so a
    click anywhere on one lies within that of its centre), summed over the seeds; dark
    where both are as near. A count of dots within a few pixels of the clicks chose the
    wrong polarity for clicks 4-6 px off the centres of dots 22 px wide (OpenPTV's
    two-camera example, github OpenPTV/example_2cam_90deg), and the route then found no
    target.
    """
    if params.dots != "auto":
        return find_dots(image, params.dots, params)
    found = {p: find_dots(image, p, params) for p in ("dark", "bright")}
    reach = params.window_px / 2.0
    off = {p: np.minimum(seed_offsets_px(d, seeds_px), reach).sum() for p, d in found.items()}
    return found["dark"] if off["dark"] <= off["bright"] else found["bright"]
