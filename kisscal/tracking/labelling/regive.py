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

The result is judged again from scratch (its sides settled, every check made) and kept
only when fewer names are doubted. A name is certain there only when the judge passes
it and, if its trajectory changed name, the trajectory fits it better than any other
name and it was given here (not by the judge's exchanges); a doubted name left on its
trajectory stays doubted. So a name given wrongly here is still flagged.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from kisscal.tracking.labelling.anatomy import Anatomy, floor_height
from kisscal.tracking.labelling.result import Labelling
from kisscal.tracking.labelling.runnerup import name_fits, name_margins, nearest_names
from kisscal.tracking.labelling.sides import name_positions

#: Cost (mm) of a name that cannot be weighed for a trajectory, and of another held name.
_BARRED_MM = 1e6


def free_anchored(held: NDArray, template: NDArray) -> NDArray[np.bool_]:
    """Per name, whether no trajectory holds it while one of its template neighbours
    (:func:`~kisscal.tracking.labelling.runnerup.nearest_names`) is held: a free name of
    a group the trial records (a free arm's names are no candidates for a leg's marker)."""
    return ~held & held[nearest_names(template)].any(axis=1)


def regiven_rows(
    pos: NDArray, anatomy: Anatomy, reference: NDArray, doubted: NDArray
) -> NDArray[np.int64]:
    """Name row of each trajectory row of ``pos`` (n, F, 3; rows by their names, NaN
    where not held): the ``doubted`` ones (bool per row) keep theirs or take a free
    anchored name (:func:`free_anchored`), whichever
    :func:`~kisscal.tracking.labelling.runnerup.name_fits` finds best against
    ``reference`` (the set's template scaled to the subject), one to one; the others
    keep theirs."""
    out = np.arange(pos.shape[0])
    held = np.isfinite(pos[..., 0]).any(axis=1)
    rows = np.flatnonzero(doubted & held)
    free = np.flatnonzero(free_anchored(held, reference))
    if not rows.size or not free.size:
        return out
    fits = name_fits(pos, reference, anatomy.heights_mm, floor_height(pos, anatomy))[rows]
    kept = fits[np.arange(rows.size), rows]
    own = np.full((rows.size, rows.size), _BARRED_MM)
    np.fill_diagonal(own, kept)
    # A free name is a candidate only where it fits better than the name held: once a
    # name moves, its neighbours' fits are weighed against a labelling no one judged.
    with np.errstate(invalid="ignore"):
        better = np.where(fits[:, free] < kept[:, None], fits[:, free], np.nan)
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
) -> Labelling:
    """``judged`` with its doubted names given again (:func:`regiven_rows`) and judged
    again by ``judge`` (a labelling -> the labelling judged), when fewer names are then
    doubted; else ``judged`` itself.

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

    Returns
    -------
    Labelling
    """
    names = anatomy.names
    doubted = np.isin(names, judged.flagged)
    if not doubted.any():
        return judged
    out = regiven_rows(name_positions(judged, names), anatomy, reference, doubted)
    given = {names[i]: names[j] for i, j in enumerate(out) if i != j}
    if not given:
        return judged
    labels = tuple(given.get(lab, lab) for lab in judged.labels)
    missing = tuple(n for n in names if n not in set(labels))
    again = judge(replace(judged, labels=labels, missing=missing, flagged=()))
    flagged = _still_doubted(judged, again, given, anatomy, reference)
    if len(flagged) >= len(judged.flagged):
        return judged
    return replace(
        again,
        flagged=tuple(n for n in names if n in flagged),
        exchanged=judged.exchanged + again.exchanged,
    )
