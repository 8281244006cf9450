"""Matches that stay in one plane of a target that is not flat.

Seeds clicked on one level of a stepped target (four corners of its top face, say) fit a
camera that places that level's points and, under a narrow view, no other: a plane's
points leave a pinhole's focal length and distance nearly interchangeable, and the
other levels' images fall between the dots. The matching then grows over that level
only, and the camera written fits it alone; its held-out points, on the same level, do
not show that it may be wrong off it. :func:`unmatched_beside_one_plane` tells the case
by the dots left among the matched ones' images (the other levels' dots), so that the
user is told to click seeds on two or more levels.

Example
-------
>>> import numpy as np
>>> from kisscal.dlt.params import DltParams
>>> # two levels of columns, between each other: the first level's 16 points matched
>>> grid = [(x, y) for x in range(0, 70, 10) for y in (0, 10, 20, 30)]
>>> target = np.array([[x, y, 10.0 * (x % 20 > 0)] for x, y in grid])
>>> dots = target[:, :2] * 2.0
>>> dot = np.where(target[:, 2] == 0, np.arange(len(target)), -1)
>>> unmatched_beside_one_plane(target, dots, dot, DltParams())
12
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.params import DltParams
from kisscal.target.match import is_planar


def unmatched_beside_one_plane(
    target_xyz: NDArray[np.float64], dots_px: NDArray[np.float64], dot: NDArray, dlt: DltParams
) -> int:
    """Dots left unmatched within the box of the matched dots when every matched point
    lies in one plane (``dlt.min_spread_ratio``) of a target that is not flat; 0 when
    the matches leave that plane or the target is flat.

    ``dot`` is each target point's dot, -1 where unmatched
    (:class:`~kisscal.target.match.TargetMatch`).
    """
    matched = dot >= 0
    if is_planar(target_xyz, dlt) or matched.sum() < 4 or not is_planar(target_xyz[matched], dlt):
        return 0
    uv = dots_px[dot[matched]]
    free = np.ones(len(dots_px), dtype=bool)
    free[dot[matched]] = False
    inside = np.all((dots_px >= uv.min(axis=0)) & (dots_px <= uv.max(axis=0)), axis=1)
    return int((inside & free).sum())
