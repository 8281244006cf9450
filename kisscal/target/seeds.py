"""What counts as a seed: a target point clicked on a camera's image.

One rule for ``kisscal validate`` and ``kisscal calibrate``: how many seeds a camera needs,
and which rows of a seeds file are clicks at all.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import in_image

#: The least number of seeds per camera: a resection's pinhole camera is 7 numbers
#: (focal length, rotation, position) and each seed gives two.
MIN_SEEDS = 4


def too_few_seeds(n: int) -> str | None:
    """Why ``n`` seeds are too few for a camera (None when they are enough)."""
    if n >= MIN_SEEDS:
        return None
    return (
        f"{n} seeds; click at least {MIN_SEEDS} target points (a camera's focal length, "
        "direction and position take 7 numbers, each seed gives 2)"
    )


def clicked(uv: NDArray[np.float64], size_px: tuple[int, int] | None) -> NDArray[np.bool_]:
    """Which seeds (n, 2) are clicks: those on an image of ``size_px`` (width, height), or,
    its size unknown, not left of or above it. MyPTV writes ``-1, -1`` for a target point
    it was not given a click for.

    Examples
    --------
    >>> clicked(np.array([[10.0, 5.0], [-1.0, -1.0]]), (640, 480)).tolist()
    [True, False]
    """
    if size_px is None:
        return np.all(np.asarray(uv) >= -0.5, axis=1)
    return in_image(uv, size_px)
