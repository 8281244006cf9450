"""The extent (width, height) of the largest markers, for the upper size limits.

Markers seen face-on image as round spots (up to the pixel aspect): their extent follows
from their area. Dots of a target seen obliquely image as ellipses, every one alike, and
a round spot of the same area is narrower than they are tall (or wide): limits from it
flag the larger dots of the target as too large. On images of a target, where the dots'
median elongation (principal axes of their moments, round units) exceeds the round-spot
bound, the largest dots' own extents are taken where they reach further. Marker frames
keep the round extents: markers blur as they move, and a merged pair or a streak must
stay too large.
"""

from __future__ import annotations

import math

import numpy as np

from kisscal.detect.appendage import ROUND_ELONGATION
from kisscal.detect.population import largest_size
from kisscal.detect.shape import PIXEL_AREA_VAR, principal_axes
from kisscal.detect.survey import Groups

#: Fewest marker-sized spots whose shape is read for their elongation.
MIN_SHAPES = 20
#: Least area (px) of a spot whose elongation is read: about 9 px across. Smaller spots'
#: moments are mostly pixel area and blur (a KISS grid dot of 20 px, 7 x 3, reads 1.2).
SHAPE_MIN_PIXELS = 64


def marker_extent(
    markers: Groups, pixels: float, aspect: float, target: bool = True
) -> tuple[float, float]:
    """Width and height (px) of the largest markers.

    Parameters
    ----------
    markers : Groups
        The surveyed marker population.
    pixels : float
        The largest markers' area (px).
    aspect : float
        Pixel aspect (width / height of a round marker's image).
    target : bool
        The images show a target (the grid kind), whose dots may be seen obliquely;
        False for marker frames, which keep the round extents.

    Returns
    -------
    tuple of float
        Width and height (px), a round spot's of ``pixels`` plus one pixel, or the
        largest elongated markers' own where they are wider or taller.
    """
    lines = 2.0 * math.sqrt(pixels / (math.pi * aspect))
    width, height = lines * aspect + 1.0, lines + 1.0
    sized = markers.take(markers.inside & (markers.pixels >= SHAPE_MIN_PIXELS))
    if not target or len(sized) < MIN_SHAPES:
        return width, height
    var_x = np.maximum(sized.var_x - PIXEL_AREA_VAR, 1e-3)
    var_y = np.maximum(sized.var_y - PIXEL_AREA_VAR, 1e-3)
    major, minor, _, _ = principal_axes(var_x, var_y, sized.cov_xy, aspect)
    if np.median(np.sqrt(major / minor)) <= ROUND_ELONGATION:
        return width, height
    return max(width, largest_size(sized.width)), max(height, largest_size(sized.height))
