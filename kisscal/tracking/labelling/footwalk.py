"""The order of a foot's markers along the walk, as the foot contest judges it.

A subject walks forward, and the foot's pitch in gait (about 20 degrees toe up at heel
strike, 50 heel up at toe off) never turns the order of its markers along the
direction the body moves (Perry & Burnfield 2010): the toe lies ahead of the heel, and
the ankle (the lateral malleolus, 85-90 mm ahead of the heel marker along the foot in
the kiss and Plug-in Gait templates, 30 mm above it) ahead of the heel and behind the toe. So a
way of giving a foot's names that puts any of these pairs the other way round is
unlikely, whatever its distances say. The heel and the ankle matter as much as the heel
and the toe: with the shank out of view their distances to each other are one number
either way round (kiss 3 cameras seed 460: the left heel's piece named ankle by the
first window, the ankle's few fields then named heel at the template's ankle-heel length,
and the toe and tibia left unnamed for want of a partner at their lengths).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: Two of a foot's names keep their order along the walk when the template puts them at
#: least this share of the heel-to-toe length apart along the heel-to-toe line: the
#: ankle, at about 0.4 of it, is ordered against both ends; a marker beside another (a
#: set's metatarsal heads) is not.
ORDER_SHARE = 0.25


def ordered_pairs(
    template: NDArray, names: NDArray, toe: int, heel: int
) -> tuple[tuple[int, int], ...]:
    """(front, back) pairs of positions in a foot's ``names`` (rows of ``template``,
    ``toe`` and ``heel`` among them) that the template puts :data:`ORDER_SHARE` of the
    heel-to-toe length apart along that line, the front one ahead."""
    axis = template[toe] - template[heel]
    along = (template[names] - template[heel]) @ axis / max(float(axis @ axis), 1e-12)
    front, back = np.nonzero(along[:, None] - along[None, :] >= ORDER_SHARE)
    return tuple(zip(front.tolist(), back.tolist(), strict=True))


def trailing(a: NDArray, b: NDArray, direction: NDArray, fraction: float) -> NDArray:
    """Whether positions ``a`` (..., F, 3) lie behind ``b`` along the walk
    ``direction`` (F, 2) in at least ``fraction`` of the fields both are seen."""
    votes = np.sum((a[..., :2] - b[..., :2]) * direction, axis=-1)
    ok = np.isfinite(votes)
    n = ok.sum(axis=-1)
    behind = np.sum(ok & (votes < 0), axis=-1)
    return (n > 0) & (behind >= fraction * np.maximum(n, 1))


def out_of_order(
    choices: NDArray, behind: NDArray, pairs: list[tuple[int, int]]
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """For each way (rows of ``choices``: a candidate per foot name position, -1 for
    none), whether it gives both names of any ordered pair (``pairs``: (front, back)
    positions) and whether it puts any such pair the other way round (``behind``:
    candidate x candidate, whether one trails the other along the walk)."""
    choices = np.atleast_2d(choices)
    given = np.zeros(choices.shape[0], dtype=bool)
    wrong = np.zeros(choices.shape[0], dtype=bool)
    for f, b in pairs:
        both = (choices[:, f] >= 0) & (choices[:, b] >= 0)
        given |= both
        wrong |= both & behind[np.maximum(choices[:, f], 0), np.maximum(choices[:, b], 0)]
    return given, wrong
