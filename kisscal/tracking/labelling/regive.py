"""Doubted names given again by the evidence that doubted them.

The judge (:func:`~kisscal.tracking.labelling.sides.judge_sides`) flags names that the
evidence the labelling did not shape contradicts
(:mod:`~kisscal.tracking.labelling.runnerup`): a trajectory's median distances to its
named neighbours and its height above the floor, against the set's own template scaled
to the subject. A flagged name is often a name pushed onto a marker of a group whose own
name was left free: a finger's name on a thigh marker with the arms absent, the thigh's
name free (Vicon_analysis.c3d without its arm markers). So each doubted trajectory
keeps its name or takes a free name of a group the trial records (one of whose template
neighbours is held), whichever fits it best, one to one (a minimum-cost assignment, Kuhn
1955); a free name is a candidate only where it fits better than the name held.
Another held name is no candidate: its holder is as doubtful, and a chain of names
permuted among doubted holders has no fixed end to hold it (test1.c3d).

A marker placed far from the template's place fits its own name worse than a free name
of another group (a thigh marker 190 mm above the template's, at wrist height, named a
wrist with the arms absent: analogfpscale03.c3d). The set's segments know better: a
doubted trajectory whose name stands alone (none of its nearest names held), that no
segment partner of that name holds rigid, but that keeps its distance to a held name
whose segment partner is free, is that partner
(:func:`vouched`, when it is the only such name): its only candidate, whatever the
template says.

The result is judged again from scratch (its sides settled, every check made) and kept
only when fewer names are doubted (the names segments vouched for alone: as many). A
name is certain there only when the judge passes it and, if its trajectory changed name,
the trajectory fits it better than any other name and it was given here (not by the
judge's exchanges); a doubted name left on its trajectory stays doubted. So a name given
wrongly here is still flagged.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from kisscal.tracking.labelling.anatomy import Anatomy, floor_height
from kisscal.tracking.labelling.result import Labelling
from kisscal.tracking.labelling.runnerup import (
    MARGIN_FIELDS,
    isolated,
    name_fits,
    name_margins,
    nearest_names,
)
from kisscal.tracking.labelling.sides import name_positions
from kisscal.tracking.labelling.state import MIN_SHARED_FIELDS, RIGID_SPREAD_MM, distance_spread

#: Cost (mm) of a name that cannot be weighed for a trajectory, and of another held name.
_BARRED_MM = 1e6


def free_anchored(held: NDArray, template: NDArray) -> NDArray[np.bool_]:
    """Per name, whether no trajectory holds it while one of its template neighbours
    (:func:`~kisscal.tracking.labelling.runnerup.nearest_names`) is held: a free name of
    a group the trial records (a free arm's names are no candidates for a leg's marker)."""
    return ~held & held[nearest_names(template)].any(axis=1)


def vouched(pos: NDArray, segments: NDArray, template: NDArray) -> NDArray[np.bool_]:
    """(n, n): name ``j`` is vouched for the trajectory named ``i`` (rows of ``pos``,
    (n, F, 3)) by the set's ``segments`` ((n, n) bool): ``j`` is free, ``i``'s name is
    isolated (none of its nearest names in ``template`` held:
    :func:`~kisscal.tracking.labelling.runnerup.isolated`), and ``i`` keeps its distance
    (SD under the rigid spread over :data:`~.state.MIN_SHARED_FIELDS` shared fields at
    least) to a held segment partner of ``j``, to none of its own name's, and to fewer
    than half the names held with it (a still body keeps every distance); ``j`` is the
    only such name.

    References
    ----------
    Shafiq et al. 2001 (rigid segment lengths as a check on a marker's identity).
    """
    seen = np.isfinite(pos[..., 0])
    fields = np.linspace(0, pos.shape[1] - 1, min(MARGIN_FIELDS, pos.shape[1])).astype(int)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # names never seen together
        sd, shared = distance_spread(pos, np.arange(len(pos)), fields, shared=True)
    together = shared >= MIN_SHARED_FIELDS
    np.fill_diagonal(together, False)
    still = together & (sd < RIGID_SPREAD_MM)
    moving = ~(still & segments).any(axis=1) & (still.sum(axis=1) < 0.5 * together.sum(axis=1))
    out = (isolated(pos, template) & moving)[:, None] & (still.astype(int) @ segments > 0)
    out &= ~seen.any(axis=1)[None, :]
    return out & (out.sum(axis=1) == 1)[:, None]  # one name only, as the segment says


def regiven_rows(
    pos: NDArray,
    anatomy: Anatomy,
    reference: NDArray,
    doubted: NDArray,
    segments: NDArray | None = None,
) -> NDArray[np.int64]:
    """Name row of each trajectory row of ``pos`` (n, F, 3; rows by their names, NaN
    where not held): the ``doubted`` ones (bool per row) keep theirs or take a free
    anchored name (:func:`free_anchored`), whichever
    :func:`~kisscal.tracking.labelling.runnerup.name_fits` finds best against
    ``reference`` (the set's template scaled to the subject), one to one; the others
    keep theirs. With the set's ``segments`` ((n, n) bool), a trajectory with a name
    :func:`vouched` for it takes that name (or keeps its own if another takes it)."""
    out = np.arange(pos.shape[0])
    held = np.isfinite(pos[..., 0]).any(axis=1)
    rows = np.flatnonzero(doubted & held)
    vouch = np.zeros((rows.size, pos.shape[0]), dtype=bool)
    if segments is not None:
        vouch = vouched(pos, segments, reference)[rows]
    free = np.flatnonzero(free_anchored(held, reference) | vouch.any(axis=0))
    if not rows.size or not free.size:
        return out
    fits = name_fits(pos, reference, anatomy.heights_mm, floor_height(pos, anatomy))[rows]
    kept = fits[np.arange(rows.size), rows]
    own = np.full((rows.size, rows.size), _BARRED_MM)
    # A vouched name is the only candidate (the segment outweighs the template); a
    # trajectory another takes it from keeps its own.
    np.fill_diagonal(own, np.where(vouch.any(axis=1), _BARRED_MM / 2, kept))
    # A free name is a candidate only where it fits better than the name held: once a
    # name moves, its neighbours' fits are weighed against a labelling no one judged.
    with np.errstate(invalid="ignore"):
        better = np.where(fits[:, free] < kept[:, None], fits[:, free], np.nan)
        better[vouch.any(axis=1)] = np.nan
        better = np.where(vouch[:, free], np.nan_to_num(fits[:, free], nan=_BARRED_MM / 4), better)
    r, c = linear_sum_assignment(np.nan_to_num(np.c_[own, better], nan=_BARRED_MM))
    took = c >= rows.size
    out[rows[r[took]]] = free[c[took] - rows.size]
    return out


def _still_doubted(
    judged: Labelling, again: Labelling, given: dict[str, str], anatomy: Anatomy, reference
) -> set[str]:
    """Names of ``again`` (``judged`` given again, ``given``: old name -> new, and judged)
    to flag: the judge's, a changed name not given here or not its trajectory's best fit
    (:func:`~kisscal.tracking.labelling.runnerup.name_margins`), a doubted name left on
    its trajectory."""
    names = anatomy.names
    row = {n: i for i, n in enumerate(names)}
    pos = name_positions(again, names)
    margins = name_margins(
        pos, reference, anatomy.heights_mm, floor_height(pos, anatomy), anatomy.pairs
    )
    with np.errstate(invalid="ignore"):
        best = margins > 0
    was = set(judged.flagged)
    flagged = set(again.flagged)
    for before, after in zip(judged.labels, again.labels, strict=True):
        if after not in row:
            continue
        if before == after and before in was:
            flagged.add(after)
        elif before != after and (given.get(before) != after or not best[row[after]]):
            flagged.add(after)
    return flagged


def regive_doubted(
    judged: Labelling,
    anatomy: Anatomy,
    reference: NDArray,
    judge: Callable[[Labelling], Labelling],
    segments: NDArray | None = None,
) -> Labelling:
    """``judged`` with its doubted names given again (:func:`regiven_rows`) and judged
    again by ``judge`` (a labelling -> the labelling judged), when fewer names are then
    doubted; else, when ``segments`` vouched for names given, those names alone, when no
    more names are doubted; else ``judged`` itself.

    Parameters
    ----------
    judged : Labelling
        A judged labelling (its ``flagged`` names are the doubted ones).
    anatomy : Anatomy
        The set's anatomy (names, pairs, heights).
    reference : (n, 3) array
        The set's template scaled to the subject, rows as ``anatomy.names``.
    judge : callable
        Judges a labelling (:func:`~kisscal.tracking.labelling.sides.judge_sides`).
    segments : (n, n) bool array, optional
        The set's rigid segments (:func:`~kisscal.tracking.labelling.state.segment_mask`):
        a name they vouch for (:func:`vouched`) is its trajectory's only candidate.

    Returns
    -------
    Labelling
    """
    names = anatomy.names
    doubted = np.isin(names, judged.flagged)
    if not doubted.any():
        return judged
    pos = name_positions(judged, names)
    out = regiven_rows(pos, anatomy, reference, doubted, segments)
    found = _given_again(judged, anatomy, reference, judge, out, 1)
    vouch = np.zeros(len(names), bool)
    if segments is not None:
        vouch = (vouched(pos, segments, reference) & (out[:, None] == np.arange(len(names)))).any(1)
    if found is judged and vouch.any():
        # The segments' evidence alone, no other name moved with it: kept, doubted or
        # not, when no more names are doubted.
        out = np.where(vouch, out, np.arange(len(names)))
        found = _given_again(judged, anatomy, reference, judge, out, 0)
    return found


def _given_again(
    judged: Labelling,
    anatomy: Anatomy,
    reference: NDArray,
    judge: Callable[[Labelling], Labelling],
    out: NDArray,
    fewer: int,
) -> Labelling:
    """``judged`` with the names of rows ``out`` (:func:`regiven_rows`) judged again,
    when at least ``fewer`` names fewer are doubted then; else ``judged`` itself."""
    names = anatomy.names
    given = {names[i]: names[j] for i, j in enumerate(out) if i != j}
    if not given:
        return judged
    labels = tuple(given.get(lab, lab) for lab in judged.labels)
    missing = tuple(n for n in names if n not in set(labels))
    again = judge(replace(judged, labels=labels, missing=missing, flagged=()))
    flagged = _still_doubted(judged, again, given, anatomy, reference)
    if len(flagged) > len(judged.flagged) - fewer:
        return judged
    return replace(
        again,
        flagged=tuple(n for n in names if n in flagged),
        exchanged=judged.exchanged + again.exchanged,
    )
