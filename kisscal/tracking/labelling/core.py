"""The core of a window: the long pieces that describe the subject's body there.

Phase 1 (and 3) matches the core's average pose to the template, and the subject's
estimates (stature, the floor, the vertical, the walking direction) are read from it.
A single long piece that is not the subject's (a marker dropped on the floor, a
reflection, a calibration object left in the volume; issue 26: a still channel 2.5 m
from a walker and 430 mm below the floor put the floor under it and made the stature
1.95 m) drags every one of those estimates. Such a piece sits far from the body's
cluster: each field's coordinate-wise median of the pieces (robust to a minority of
outliers, Rousseeuw & Leroy 1987) is inside the body, and a body's markers keep within a
few times their median distance to it (feet and a raised hand about 2-3 times).
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray

#: A piece is not the subject's when its median distance (over the window's fields) to
#: the pieces' median point is over this many times the pieces' median such distance: a
#: standing body's farthest markers (feet, a hand raised) sit at about 2-3 times.
FAR_FACTOR = 4.0
#: The body walks when its median point travels over this many times its scale (the
#: pieces' median distance to it) in a window: 0.8 m or more in the 1 s first window.
WALKED_FACTOR = 2.0
#: A piece is still while the body walks when it spans under this fraction of the
#: body's travel: in a 1 s window of a walk every foot swings (stance lasts 0.6-0.7 s,
#: Perry 1992), and a swing moves it 0.3 m and more.
STILL_FRACTION = 0.1
#: Fewest pieces whose median point and distance are trusted to tell a stray one.
MIN_CLUSTER = 5
#: The trial holds only part of the set when at least this fraction of its names finds no
#: piece within a label tolerance, one to one, in the average pose stood on the template.
PARTIAL_FRACTION = 1 / 3


def far_from_body(pos: NDArray) -> NDArray[np.bool_]:
    """Which pieces (``pos``: k pieces x fields x 3, NaN where unseen) sit far from the
    body's cluster (see :data:`FAR_FACTOR`); none with fewer than :data:`MIN_CLUSTER`.

    References
    ----------
    Rousseeuw & Leroy 1987 (the median as a centre and scale that a minority of
    outliers cannot carry away).
    """
    k = pos.shape[0]
    if k < MIN_CLUSTER:
        return np.zeros(k, dtype=bool)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # fields or pieces unseen
        centre = np.nanmedian(pos, axis=0)
        distance = np.nanmedian(np.linalg.norm(pos - centre[None], axis=2), axis=1)
    scale = np.nanmedian(distance)
    if not np.isfinite(scale) or scale <= 0:
        return np.zeros(k, dtype=bool)
    far = np.nan_to_num(distance, nan=0.0) > FAR_FACTOR * scale
    return far | _still(pos, centre, scale)


def _still(pos: NDArray, centre: NDArray, scale: float) -> NDArray[np.bool_]:
    """Pieces that stay put while the body's median point travels over
    :data:`WALKED_FACTOR` times the body's scale."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # fields or pieces unseen
        travel = np.linalg.norm(np.nanmax(centre, axis=0) - np.nanmin(centre, axis=0))
        extent = np.linalg.norm(np.nanmax(pos, axis=1) - np.nanmin(pos, axis=1), axis=1)
    if not travel > WALKED_FACTOR * scale:
        return np.zeros(pos.shape[0], dtype=bool)
    return np.nan_to_num(extent, nan=np.inf) < STILL_FRACTION * travel


def core_pieces(present: NDArray, rich: NDArray, dense: NDArray | None = None) -> NDArray[np.int64]:
    """Long pieces seen in at least 60 % of ``rich``, every pair of them seen together,
    and (given their positions ``dense``: pieces x fields x 3) none far from the body's
    cluster (:func:`far_from_body`).

    Every pair of core pieces must share rich fields for a median distance; the piece
    missing most pairs is dropped until they all do (two pieces of one marker never meet).
    """
    core = np.flatnonzero(present[:, rich].mean(axis=1) >= 0.6)
    if dense is not None and core.size:
        core = core[~far_from_body(dense[np.ix_(core, rich)])]
    while core.size >= 3:
        seen = present[np.ix_(core, rich)].astype(int)
        never = ((seen @ seen.T) == 0).sum(axis=1)
        if never.max() == 0:
            break
        core = np.delete(core, int(np.argmax(never)))
    return core


def held_whole(held: int, n_names: int) -> bool:
    """Whether ``held`` names of ``n_names`` are (nearly) the whole set
    (:data:`PARTIAL_FRACTION`)."""
    return held >= (1 - PARTIAL_FRACTION) * n_names


def crowded(n_pieces: int, n_names: int) -> bool:
    """Whether a window holds more pieces than the set has names by over
    :data:`PARTIAL_FRACTION`: markers of another set beside it (issue 26: pyCGM's
    Movement_trial, 42 cluster and foot markers beside the 39 of Plug-in Gait), which the
    swap search, naming only the pieces its start picked, would let take the set's names."""
    return n_pieces > (1 + PARTIAL_FRACTION) * n_names
