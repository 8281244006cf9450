"""How far each name's evidence sets it apart from its runner-up.

The anatomy (:mod:`~kisscal.tracking.labelling.anatomy`) checks relations that a wrong
name can satisfy as well as the right one: a wrist bar's two markers (``WRA``, ``WRB``)
lie at one height on one side, and a foot whose names moved round by one (the toe named
ankle, the ankle named heel, in a file with no heel marker) still has its front name
ahead of its back one. And the subject's template, fitted to the names the labelling gave
(:func:`~kisscal.tracking.labelling.subject.fit_template`), confirms whatever it was
fitted to. So each name is also weighed against every other name of the set on evidence
the labelling did not shape (:func:`name_margins`): the trajectory's median distances to
its named neighbours and its height above the floor, against the set's own template
(scaled to the subject). A name is only as good as its margin over the best other name
that trajectory could take (a name held elsewhere is taken by exchange, the other
trajectory getting this one's name); below ``min_name_margin_mm`` it is flagged.
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray

#: Neighbours: named trajectories whose median distance is below this fraction of the
#: subject's stature (a foot's names weighed by the shank and foot, not the head).
NEIGHBOUR_FRACTION = 0.35
#: Fields sampled (evenly) for the median distances.
MARGIN_FIELDS = 200


def median_distances(pos: NDArray) -> NDArray[np.float64]:
    """(n, n) median distance between named trajectories over the fields both are seen
    in (NaN when never together), over at most :data:`MARGIN_FIELDS` fields."""
    seen = np.isfinite(pos[..., 0]).any(axis=0)
    fields = np.flatnonzero(seen)
    fields = fields[np.linspace(0, fields.size - 1, min(MARGIN_FIELDS, fields.size)).astype(int)]
    p = pos[:, fields]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # pairs never seen together
        return np.nanmedian(np.linalg.norm(p[:, None] - p[None, :], axis=3), axis=2)


def name_margins(
    pos: NDArray,
    template: NDArray,
    heights_mm: NDArray | None,
    floor_mm: float,
    pairs: tuple[tuple[int, int], ...] = (),
) -> NDArray[np.float64]:
    """Per name (rows of ``pos``, (n, F, 3), Z up), the margin (mm) of its trajectory's
    fit to its own name over the fit to the best other name (NaN: not seen, or no
    neighbour).

    The fit of trajectory ``i`` to name ``j`` is the median, over its neighbours ``k``
    (:data:`NEIGHBOUR_FRACTION` of the template's height) and the floor, of the absolute
    difference between the measured median distance ``i``-``k`` (height above
    ``floor_mm``) and the template's distance between ``j`` and ``k``'s name (``j``'s
    height in ``heights_mm``; without them, or without a floor, distances alone); when
    ``j`` is ``k``'s name, the two exchange, and ``k`` is weighed as ``i``'s name. A
    name's mirror partner (``pairs``: left, right) is no runner-up: distances cannot
    tell a body from its mirror image, the anatomy's sides do.
    """
    n = pos.shape[0]
    stature = float(np.ptp(template[:, 2]))
    known = heights_mm is not None and np.isfinite(floor_mm)
    mirror = np.arange(n)
    for a, b in pairs:
        mirror[a], mirror[b] = b, a
    measured = median_distances(pos)
    tdist = np.linalg.norm(template[:, None] - template[None, :], axis=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # names never seen
        height = np.nanmedian(pos[..., 2], axis=1) - (floor_mm if known else 0.0)
    margins = np.full(n, np.nan)
    for i in np.flatnonzero(np.isfinite(height)):
        near = np.isfinite(measured[i]) & (measured[i] < NEIGHBOUR_FRACTION * stature)
        near[i] = False
        k = np.flatnonzero(near)
        if k.size == 0:
            continue
        # (candidate name j, neighbour k): the template distance of j to k's name, k's
        # name being i when k is named j (an exchange).
        partner = np.where(k[None, :] == np.arange(n)[:, None], i, k[None, :])
        misfit = np.abs(measured[i, k][None, :] - tdist[np.arange(n)[:, None], partner])
        if known:
            misfit = np.c_[misfit, np.abs(height[i] - heights_mm)]
        fit = np.median(misfit, axis=1)
        others = np.delete(fit, np.unique([i, mirror[i]]))
        margins[i] = float(others.min() - fit[i])
    return margins
