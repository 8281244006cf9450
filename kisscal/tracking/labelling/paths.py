"""A piece named by the trajectory it continues, seen from its segment and the next.

With few cameras a foot's markers are often hidden together, so a piece of one of them
is seen with no rigid partner: spreading (:mod:`.spread`) has only the body fit to name
it, which places the standing template around the piece, and a walking foot sits 80-130
mm off that (:mod:`.feet`). Where the piece steps from tells instead: seen from the
markers of the name's segment and the next (a toe's from the foot's and the shank's),
which move with it, a piece continues its own marker's trajectory and not a neighbour's.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.pieces import reaches, step_from
from kisscal.tracking.labelling.state import LabelState


def segment_path(
    state: LabelState, fields: NDArray, xyz: NDArray, names: NDArray, rigid: NDArray
) -> NDArray[np.int8]:
    """Per name of ``names``, whether a piece (``xyz`` at ``fields``) continues that
    name's trajectory where it steps from it (:func:`~.pieces.step_from`): 1 when it
    reaches every end beside it (:func:`~.pieces.reaches`), -1 when it misses one, 0
    when the trajectory has no sample beside the piece.

    A step is seen from the names along the name's segment and the next (two steps over
    the ``rigid`` pairs: a toe's from the foot's and the shank's), held at both ends,
    which move with it: a foot whose own markers are hidden swings with the shank.
    """
    pos = state.name_pos
    at = {int(fields[0]): xyz[0], int(fields[-1]): xyz[-1]}
    out = np.zeros(names.size, dtype=np.int8)
    for i, j in enumerate(names.tolist()):
        chain = rigid[j] | rigid[rigid[j]].any(axis=0)
        chain[j] = False
        ends = step_from(np.isfinite(pos[j, :, 0]), int(fields[0]), int(fields[-1]))
        if ends:
            kept = all(reaches(pos[j], pos[chain], x, y, at[y]) for x, y in ends)
            out[i] = 1 if kept else -1
    return out


def by_segment_path(state: LabelState, t: int, names: NDArray, rigid: NDArray, j: int) -> int:
    """The name piece ``t`` takes of ``names`` when the body fit gave it ``j`` with no
    rigid partner in view: the one name whose trajectory it continues
    (:func:`segment_path`) when it misses ``j``'s; ``j`` otherwise.

    The body fit places the standing template around the piece; a walking foot sits
    80-130 mm off it (:mod:`.feet`), so with the foot's other markers hidden its toe
    lands nearer the heel's expected place (modern 3 cameras seed 443: LTOE's piece
    named LHEE, 86 against 142 mm), while seen from the shank it steps on from where
    the toe's trajectory left off (51 mm in 20 fields; from the heel's, 245 mm in 5).
    """
    fields, xyz = state.piece(t)
    path = segment_path(state, fields, xyz, names, rigid)
    kept = names[path == 1]
    if path[names == j][0] < 0 and kept.size == 1:
        return int(kept[0])
    return j
