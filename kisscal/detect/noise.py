"""Noise removal (Shafiq et al. 2001, section 2.2)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.detect.groups import GroupTable
from kisscal.detect.params import DetectionParams


def noise_groups(table: GroupTable, params: DetectionParams) -> NDArray[np.bool_]:
    """Mark the groups that section 2.2 calls noise.

    Parameters
    ----------
    table : GroupTable
        Measured groups.
    params : DetectionParams
        ``remove_lonely``, ``remove_one_pixel_wide``, ``remove_one_pixel_high`` and the
        former method's ``noise_min_width_px`` / ``noise_min_height_px``.

    Returns
    -------
    ndarray of bool
        True for each noise group (lonely pixels, one-pixel-wide or one-pixel-high groups,
        groups both narrower and lower than the minimum).
    """
    w, h = table.width, table.height
    noise = (w < params.noise_min_width_px) & (h < params.noise_min_height_px)
    if params.remove_lonely:
        noise |= table.pixels == 1
    if params.remove_one_pixel_wide:
        noise |= w == 1
    if params.remove_one_pixel_high:
        noise |= h == 1
    return noise
