"""Overlay of detected blobs on their image, for a technician to see what was found.

Each blob's envelope (the ellipse inscribed in its bounding rectangle, as in the marker
envelopes of Shafiq et al. 2001, Figs. 7 and 9) and its centroid are drawn, valid blobs in green,
invalid ones (size limits) in red. The caller writes the returned array as a PNG.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from kisscal.detect.blobs import Blobs
from kisscal.errors import InputError

VALID_RGB = (40, 220, 40)
INVALID_RGB = (235, 40, 40)
_SHIFT = 4  # cv2 fixed-point bits: draw at 1/16 pixel


def draw_overlay(
    image: NDArray, blobs: Blobs, scale: tuple[int, int] = (2, 4)
) -> NDArray[np.uint8]:
    """Return an RGB uint8 image of ``image`` with ``blobs`` drawn on it.

    Parameters
    ----------
    image : ndarray, shape (h, w)
        The grey (or boolean) image the blobs were detected in.
    blobs : Blobs
        Detection result of that image.
    scale : (int, int)
        Integer enlargement along x and y. The default (2, 4) makes the non-square pixels
        of 752 x 291 fields look square and leaves room for the marks.

    Returns
    -------
    ndarray of uint8, shape (h * scale[1], w * scale[0], 3)
    """
    if not isinstance(image, np.ndarray) or image.ndim != 2 or image.size == 0:
        raise InputError("overlay: expected a non-empty 2-D image")
    sx, sy = (int(s) for s in scale)
    if sx < 1 or sy < 1:
        raise InputError(f"overlay: scale must be positive integers, got {scale}")
    grey = image.astype(np.float64)
    if image.dtype == np.bool_:
        grey *= 255.0
    elif grey.max() > 255:
        grey *= 255.0 / grey.max()
    grey = np.clip(grey, 0, 255).astype(np.uint8)
    big = np.repeat(np.repeat(grey, sy, axis=0), sx, axis=1)
    rgb = np.ascontiguousarray(np.stack([big, big, big], axis=-1))
    one = 1 << _SHIFT
    for i in range(len(blobs)):  # a few dozen marks per image: drawing, not a hot path
        colour = VALID_RGB if blobs.valid[i] else INVALID_RGB
        # Pixel centres sit at (i + 0.5) * scale - 0.5 in the enlarged image.
        cx = ((blobs.x_px[i] + 0.5) * sx - 0.5) * one
        cy = ((blobs.y_px[i] + 0.5) * sy - 0.5) * one
        ax = blobs.w_px[i] * sx / 2 * one
        ay = blobs.h_px[i] * sy / 2 * one
        centre = (round(cx), round(cy))
        cv2.ellipse(rgb, centre, (round(ax), round(ay)), 0, 0, 360, colour, 1, cv2.LINE_8, _SHIFT)
        (u, v), arm = centre, 3 * one
        for a, b in (((u - arm, v), (u + arm, v)), ((u, v - arm), (u, v + arm))):  # a cross
            cv2.line(rgb, a, b, colour, 1, cv2.LINE_8, _SHIFT)
    return rgb
