"""A foot name judged by its rigid partner when nothing named is seen with it.

The foot contest (:func:`~kisscal.tracking.labelling.feet.settle_feet`) judges a piece
holding a foot name by its distances to the shank and to the foot's other names, and by
their order along the walk. With three cameras a foot can hold one name alone: the knee
never seen, the tibia and the foot's other markers unnamed. The first window names such
a piece from distances across joints (to the pelvis, to the other leg), which the walk
biases: the feet pass each other, so a median distance across them is not the standing
one, and a toe can take the ankle's name (kiss 3 cameras, seed 469: the right toe named
ankle through the trial, its heel in three unnamed pieces, 345 identity switches). The
foot's own markers can still tell: they are one rigid segment (Winter 2009), so an
unnamed piece rigid to the named one lies at the template's distance between their two
names. When that distance fits no pair with the piece's name but one other pair of the
foot's names, the name is wrong, and the two pieces take that pair, the one ahead along
the walk the front name (the toe ahead of the heel and of the ankle, the ankle ahead of
the heel, :mod:`~kisscal.tracking.labelling.footwalk`).
"""

from __future__ import annotations

import warnings
from itertools import combinations

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.footwalk import trailing
from kisscal.tracking.labelling.state import MIN_SHARED_FIELDS, RIGID_SPREAD_MM, LabelState

#: Fields a piece must share with a name for their distance to count (the foot contest's).
MIN_SHARED = 3


def name_distances(state: LabelState, fields: NDArray, xyz: NDArray, refs: NDArray) -> NDArray:
    """Median distance from positions ``xyz`` (at ``fields``) to each name of ``refs``
    over the fields both are seen, NaN when fewer than :data:`MIN_SHARED`."""
    d = np.linalg.norm(state.name_pos[refs][:, fields] - xyz[None], axis=2)
    shared = np.isfinite(d).sum(axis=1) >= MIN_SHARED
    out = np.full(refs.size, np.nan)
    if shared.any():
        out[shared] = np.nanmedian(d[shared], axis=1)
    return out


def rigid_partners(state: LabelState, fields: NDArray, xyz: NDArray) -> list[tuple[int, float]]:
    """(piece, median distance) of the unnamed long pieces rigid to positions ``xyz`` (at
    ``fields``): seen with them in :data:`MIN_SHARED_FIELDS` fields or more, their distance's
    SD under :data:`RIGID_SPREAD_MM`; most shared fields first."""
    rows = np.flatnonzero(state.label_of[state.long_ids] < 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # pieces never seen with it
        d = np.linalg.norm(state.dense[rows][:, fields] - xyz[None], axis=2)
        spread, median = np.nanstd(d, axis=1), np.nanmedian(d, axis=1)
    shared = np.isfinite(d).sum(axis=1)
    ok = np.flatnonzero((shared >= MIN_SHARED_FIELDS) & (spread < RIGID_SPREAD_MM))
    ok = ok[np.argsort(-shared[ok], kind="stable")]
    return [(int(state.long_ids[rows[r]]), float(median[r])) for r in ok]


def fitting_pairs(
    distance: NDArray, names: NDArray, tolerance: float, length: float
) -> list[tuple[int, int]]:
    """Pairs (positions in ``names``) whose template ``distance`` (names x names, of the
    set) lies within ``tolerance`` of ``length``."""
    pairs = combinations(range(names.size), 2)
    return [(a, b) for a, b in pairs if abs(distance[names[a], names[b]] - length) <= tolerance]


def settle_lone_foot_names(
    state: LabelState, names: NDArray, shank: NDArray, order: tuple, direction: NDArray
) -> bool:
    """Rename each piece holding one of a foot's ``names`` that is seen with none of the
    foot's other names nor the ``shank`` and whose longest-seen rigid unnamed partner
    (:func:`rigid_partners`) lies at a distance fitting, within
    ``label_segment_tolerance_mm``, no pair of the foot's names with its name but one
    other pair (:func:`fitting_pairs`): the piece and the partner take that pair, the one
    ahead along the walk ``direction`` in ``facing_fraction`` of their shared fields the
    front name of ``order`` ((front, back) positions in ``names``), when both names are
    free in both pieces' fields. Returns whether any name moved.
    """
    params = state.params
    moved = False
    for p in np.flatnonzero(np.isin(state.label_of, names)).tolist():
        n = int(state.label_of[p])
        fields, xyz = state.piece(p)
        judges = np.concatenate([shank, names[names != n]])
        partners = rigid_partners(state, fields, xyz)
        if not partners or np.isfinite(name_distances(state, fields, xyz, judges)).any():
            continue
        q, length = partners[0]
        pairs = fitting_pairs(
            state.template_distance, names, params.label_segment_tolerance_mm, length
        )
        if len(pairs) != 1 or n in names[list(pairs[0])]:
            continue  # its name fits its partner, or the distance tells no pair
        a, b = pairs[0]
        front, back = (a, b) if (a, b) in order else (b, a) if (b, a) in order else (-1, -1)
        f_q, x_q = state.piece(q)
        both, i, k = np.intersect1d(fields, f_q, return_indices=True)
        p_ahead = trailing(x_q[k], xyz[i], direction[both], params.facing_fraction)
        q_ahead = trailing(xyz[i], x_q[k], direction[both], params.facing_fraction)
        if front < 0 or p_ahead == q_ahead:
            continue  # the walk does not order them
        span = np.union1d(fields, f_q)
        if np.isfinite(state.name_pos[names[[a, b]]][:, span, 0]).any():
            continue
        state.name_pos[n, fields] = np.nan
        state.name_piece(p, int(names[front] if p_ahead else names[back]))
        state.name_piece(q, int(names[back] if p_ahead else names[front]))
        moved = True
    return moved
