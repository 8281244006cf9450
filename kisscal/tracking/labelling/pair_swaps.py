"""Given rigid pairs of a window's core pieces named the wrong way round.

Two markers of one segment seen without their neighbours can swap names at no cost in
the distances the window matches by; the way the pair points in the rigid fit of the
other named pieces tells (:func:`pair_direction`), and a pair that points backwards is
exchanged, or one of its names given to the segment's free third marker
(:func:`free_name_variant`).

References
----------
Kabsch 1976 (the rigid fit); Shafiq et al. 2001 (labelling markers by rigid segments).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.state import LabelState
from kisscal.tracking.rigid import field_fits, kabsch

# A given rigid pair whose pieces point the other way than their names in more than this
# fraction of the window's fields is exchanged (:func:`pair_direction`).
PAIR_DIRECTION = 2 / 3


def settle_rigid_swaps(
    state: LabelState, core: NDArray, rich: NDArray, assign: NDArray, fit_rms: float
) -> tuple[float, NDArray[np.int64]]:
    """Exchange the names of two core pieces named as a given rigid pair when they point
    the other way than their names in most fields (:func:`pair_direction`), or when the
    real fields' rigid fit is clearly better so and their direction does not confirm
    their names.

    Two markers of one segment seen without their neighbours (a heel and a toe of a foot
    whose ankle is hidden) can swap names at no cost in distances. A pair pointing the
    wrong way may instead hold one name of the segment's free third marker
    (:func:`free_name_variant`): then that name goes to it.
    """
    rigid = state.given_rigid[np.ix_(assign, assign)]
    for a, b in zip(*np.nonzero(np.triu(rigid, 1)), strict=True):
        if assign[a] < 0 or assign[b] < 0:
            continue
        variant = assign.copy()
        variant[[a, b]] = assign[[b, a]]
        ok = variant >= 0
        rms = field_fits(state.dense, rich, core[ok], variant[ok], state.template)
        if not rms.size:
            continue
        agree = pair_direction(state, core, rich, assign, a, b)
        # The median fit of a walking body to the standing template is poor (legs swing,
        # 100-150 mm): a few percent on it is no evidence against a pair that points the
        # way its names do in most fields, so only an unconfirmed pair goes by the fit.
        by_fit = np.median(rms) < 0.95 * fit_rms and not agree >= PAIR_DIRECTION
        if agree < 1 - PAIR_DIRECTION:
            exchange = (1.0 - agree, float(np.median(rms)))
            free = free_name_variant(state, core, rich, assign, a, b, exchange)
            if free is not None:
                ok = free >= 0
                variant = free
                rms = field_fits(state.dense, rich, core[ok], variant[ok], state.template)
        if by_fit or agree < 1 - PAIR_DIRECTION:
            fit_rms, assign = (float(np.median(rms)) if rms.size else fit_rms), variant
    return fit_rms, assign


def free_name_variant(
    state: LabelState,
    core: NDArray,
    rich: NDArray,
    assign: NDArray,
    a: int,
    b: int,
    exchange: tuple[float, float],
) -> NDArray[np.int64] | None:
    """Names ``assign`` with core piece ``a`` or ``b`` (named as a given rigid pair that
    points the wrong way) given instead a name no core piece holds, rigid with the other's,
    when the pair then points the way its names do in more fields than the exchange does,
    or in as many with a better rigid fit of the window (``exchange``: the exchange's
    :func:`pair_direction` and median fit RMS); None when no such name does better.

    A wrong direction says that one of the two names is wrong, not that they are
    exchanged: in a pelvis near equilateral whose third marker is out of the window, an
    ASIS named sacrum beside the other ASIS points backwards too, and the exchange makes
    two wrong names of one (kiss 3 cameras seed 468: 590 identity switches). Where the
    exchange, too, points its names' way in every field (the two ASIS, one named sacrum:
    either order of left ASIS and sacrum points left), only the fit tells them apart: the
    exchange moves the left ASIS to the sacrum's place (kiss 3 seed 473: 347 switches).
    """
    free = np.setdiff1d(np.arange(len(state.names)), assign[assign >= 0])
    best, most = None, (exchange[0], -exchange[1])
    for piece, other in ((a, b), (b, a)):
        for name in free[state.given_rigid[free, assign[other]]].tolist():
            variant = assign.copy()
            variant[piece] = name
            agree = pair_direction(state, core, rich, variant, a, b)
            if not agree >= most[0]:
                continue
            ok = variant >= 0
            rms = field_fits(state.dense, rich, core[ok], variant[ok], state.template)
            key = (agree, -float(np.median(rms)) if rms.size else -np.inf)
            if key > most:
                best, most = variant, key
    return best


def pair_direction(
    state: LabelState, core: NDArray, rich: NDArray, assign: NDArray, a: int, b: int
) -> float:
    """Fraction of ``rich`` fields in which core pieces ``a`` and ``b`` point the way
    their names do: the vector between them, turned into the template's frame by the
    rigid fit of the other named core pieces, on the side of the template's vector
    between the names (NaN without such a field).

    A heel and a toe exchanged point backwards whatever the joints do; their distances
    to the rest of the body, averaged over a stride, may favour either.
    """
    others = np.flatnonzero(assign >= 0)
    others = others[(others != a) & (others != b)]
    want = state.template[assign[a]] - state.template[assign[b]]
    votes = []
    for f in rich:
        seen = others[np.isfinite(state.dense[core[others], f, 0])]
        pair = state.dense[core[[a, b]], f]
        if seen.size < 3 or not np.isfinite(pair).all():
            continue
        r, _ = kabsch(state.dense[core[seen], f], state.template[assign[seen]])
        votes.append(float((pair[0] - pair[1]) @ r.T @ want) > 0)
    return float(np.mean(votes)) if votes else float("nan")
