"""Whether another name fits a trajectory clearly better than its own.

The anatomy (:mod:`~kisscal.tracking.labelling.anatomy`) checks relations that a wrong
name can satisfy as well as the right one: a leg whose names moved up by one (the thigh's
name on the knee marker, the knee's on a foreign marker below it) still has every upper
name above its lower one and near its template height within the anatomy's tolerance.
And the subject's template, fitted to the names the labelling gave
(:func:`~kisscal.tracking.labelling.subject.fit_template`), confirms whatever it was
fitted to. So each name is also weighed against every other name of the set on evidence
the labelling did not shape (:func:`name_margins`): the trajectory's median distances to
its named neighbours and its height above the floor, against the set's own template
(scaled to the subject; what scale remains between the two is measured over all named
neighbours and taken out). A name that another name fits by more than
``name_deficit_fraction`` of stature better is flagged.

On real files, against a generic template, right names fall short of their runner-up
by up to about 20 mm (marker placement differs from the template's); so the margin
cannot certify a name (most names would have to be flagged), it can only catch a name
that the evidence clearly contradicts.
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray

#: Neighbours: named trajectories whose median distance is below this fraction of the
#: template's height (a foot's names weighed by the shank and foot, not the head).
NEIGHBOUR_FRACTION = 0.35
#: Fields sampled (evenly) for the median distances.
MARGIN_FIELDS = 200


def median_distances(pos: NDArray) -> NDArray[np.float64]:
    """(n, n) median distance between named trajectories over the fields both are seen
    in (NaN when never together), over at most :data:`MARGIN_FIELDS` fields."""
    fields = np.flatnonzero(np.isfinite(pos[..., 0]).any(axis=0))
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
    fit to its own name over its fit to the best other name (NaN: not seen, or no
    neighbour).

    The fit of trajectory ``i`` to name ``j`` is the median, over its neighbours ``k``
    (:data:`NEIGHBOUR_FRACTION` of the template's height) and the floor, of the absolute
    difference between the measured median distance ``i``-``k`` (height above
    ``floor_mm``), divided by the trial's scale to the template, and the template's
    distance between ``j`` and ``k``'s name (``j``'s height in ``heights_mm``; without
    them, or without a floor, distances alone); when ``j`` is ``k``'s name, the two
    exchange, and ``k`` is weighed as ``i``'s name. A name's mirror partner (``pairs``:
    left, right) is no runner-up: distances cannot tell a body from its mirror image,
    the anatomy's sides do.
    """
    n = pos.shape[0]
    measured = median_distances(pos)
    tdist = np.linalg.norm(template[:, None] - template[None, :], axis=2)
    near = np.isfinite(measured) & (measured < NEIGHBOUR_FRACTION * float(np.ptp(template[:, 2])))
    np.fill_diagonal(near, False)
    if not near.any():
        return np.full(n, np.nan)
    scale = float(np.median(measured[near] / np.maximum(tdist[near], 1.0)))
    measured = measured / scale
    known = heights_mm is not None and np.isfinite(floor_mm)
    mirror = np.arange(n)
    for a, b in pairs:
        mirror[a], mirror[b] = b, a
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # names never seen
        height = (np.nanmedian(pos[..., 2], axis=1) - (floor_mm if known else 0.0)) / scale
    margins = np.full(n, np.nan)
    rows = np.arange(n)[:, None]
    for i in np.flatnonzero(near.any(axis=1) & np.isfinite(height)):
        k = np.flatnonzero(near[i])
        # (candidate name j, neighbour k): the template distance of j to k's name, k's
        # name being i when k is named j (an exchange).
        partner = np.where(k[None, :] == rows, i, k[None, :])
        misfit = np.abs(measured[i, k][None, :] - tdist[rows, partner])
        if known:
            misfit = np.c_[misfit, np.abs(height[i] - heights_mm)]
        fit = np.median(misfit, axis=1)
        margins[i] = float(np.delete(fit, np.unique([i, mirror[i]])).min() - fit[i])
    return margins
