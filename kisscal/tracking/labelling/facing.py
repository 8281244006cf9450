"""Which of two window matches to keep: a body turned round never wins.

With few cameras the first window is often short, and its average pose can fit the
template as well turned round about the vertical (heels named toes, left named right,
the sacrum named an ASIS): such a body is proper (no mirror image), its distances nearly
the template's, and a few points added near a marker tip one way or the other. The
walk can tell: a subject walks forward, so toe markers lie ahead of heel markers, and
anterior pelvis markers ahead of posterior ones, along the direction the body moves
(lab Z up, as :mod:`~kisscal.tracking.labelling.anatomy` assumes).
:func:`facing` measures that for a match; :func:`better` keeps the match that faces
forward, else the one naming more pieces if it agrees with the other's names.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.state import LabelState

#: The body moves at least this far (mm, horizontally) through a window for its
#: walking direction to count.
MIN_TRAVEL_MM = 100.0
#: A match whose front names lie ahead of their back names in at least this fraction of
#: the votes faces forward; in at most 1 - FACING of them it is turned round.
FACING = 2 / 3
_HEEL = re.compile(r"^(.*)(HEE|HEEL|CAL)$")
_FRONT = re.compile(r"ASI")
_BACK = re.compile(r"PSI|SACR?$")


def foot_pairs(names: tuple[str, ...]) -> list[tuple[int, int]]:
    """(toe, heel) name pairs: ``<side>TOE`` and ``<side>HEE`` (or ``HEEL``, ``CAL``)."""
    index = {n: i for i, n in enumerate(names)}
    found = [(m.group(1) + "TOE", n) for n in names if (m := _HEEL.match(n))]
    return [(index[toe], index[heel]) for toe, heel in found if toe in index]


def front_back_pairs(names: tuple[str, ...]) -> tuple[tuple[int, int], ...]:
    """(front, back) name pairs the naming convention gives: toes ahead of heels
    (:func:`foot_pairs`), each ``*ASI*`` ahead of each ``*PSI*`` or ``SACR``."""
    pairs = foot_pairs(names)
    front = [i for i, n in enumerate(names) if _FRONT.search(n)]
    back = [i for i, n in enumerate(names) if _BACK.search(n)]
    pairs += [(f, b) for f in front for b in back]
    return tuple(pairs)


def facing(state: LabelState, core: NDArray | None, assign: NDArray, rich: NDArray) -> float:
    """Fraction of (front/back pair, field) votes in which a match's front-named piece
    lies ahead of its back-named one along the walking direction (NaN without a vote:
    no such pair named, or the body does not travel :data:`MIN_TRAVEL_MM`).

    The walking direction is the median horizontal displacement of the core pieces
    from the first to the last third of the fields ``rich`` span.
    """
    pairs = front_back_pairs(state.names)
    if core is None or not pairs or rich.size < 3:
        return float("nan")
    row = {int(j): int(core[k]) for k, j in enumerate(assign) if j >= 0}
    pairs = [(row[a], row[b]) for a, b in pairs if a in row and b in row]
    if not pairs:
        return float("nan")
    third = max((rich[-1] - rich[0] + 1) // 3, 1)
    early = state.dense[core, rich[0] : rich[0] + third, :2]
    late = state.dense[core, rich[-1] + 1 - third : rich[-1] + 1, :2]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # pieces unseen in a third
        travel = np.nanmedian(np.nanmean(late, axis=1) - np.nanmean(early, axis=1), axis=0)
    if not np.all(np.isfinite(travel)) or np.linalg.norm(travel) < MIN_TRAVEL_MM:
        return float("nan")
    front, back = np.array(pairs).T
    ahead = (state.dense[np.ix_(front, rich)] - state.dense[np.ix_(back, rich)])[..., :2]
    votes = ahead @ travel
    votes = votes[np.isfinite(votes)]
    return float(np.mean(votes > 0)) if votes.size else float("nan")


def _side(value: float) -> int:
    """+1 facing forward, -1 turned round, 0 unknown."""
    if value >= FACING:
        return 1
    return -1 if value <= 1 - FACING else 0


def agrees(found_core: NDArray, found_assign: NDArray, core: NDArray, assign: NDArray) -> bool:
    """Whether a match (``core``, ``assign``) gives another's names to at least half of
    the pieces both name (True when they share none)."""
    named = dict(zip(found_core[found_assign >= 0], found_assign[found_assign >= 0], strict=True))
    shared = [(named[k], j) for k, j in zip(core, assign, strict=True) if j >= 0 and k in named]
    return 2 * sum(x == y for x, y in shared) >= len(shared)


def better(state: LabelState, found, other) -> bool:
    """Whether window match ``other`` should replace ``found``
    (:class:`~kisscal.tracking.labelling.window.WindowMatch` both).

    A match facing forward (:func:`facing`) beats one turned round, whatever they name;
    otherwise ``other`` must name more pieces and agree with ``found`` on at least half
    of the pieces both name: a short window's pose does not average out the legs' swing, so it adds
    names, it does not overrule longer windows alone.
    """
    n_other = 0 if other.core is None else int(np.sum(other.assign >= 0))
    if found.core is None or n_other == 0:
        return n_other > 0
    a = _side(facing(state, found.core, found.assign, found.rich))
    b = _side(facing(state, other.core, other.assign, other.rich))
    if a != b and -1 in (a, b):
        return b > a
    return n_other > int(np.sum(found.assign >= 0)) and agrees(
        found.core, found.assign, other.core, other.assign
    )


#: Fields either side over which a name's displacement gives the walking direction.
STEP_FIELDS = 5


def walking_direction(name_pos: NDArray) -> NDArray[np.float64]:
    """Per field, the horizontal direction the body moves (F, 2), not normalised: the
    median over the names held of their displacement over :data:`STEP_FIELDS` fields
    either side (NaN where unknown)."""
    k = STEP_FIELDS
    out = np.full((name_pos.shape[1], 2), np.nan)
    step = name_pos[:, 2 * k :, :2] - name_pos[:, : -2 * k, :2]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # fields with no name held
        out[k:-k] = np.nanmedian(step, axis=0)
    return out


def settle_feet(state: LabelState) -> bool:
    """Heel and toe pieces of one foot named the wrong way round, renamed.

    A short piece named heel or toe by the body fit (whose expected positions, placed
    from the knee and thigh, are off by a step while the foot rolls) decides the name of
    the long piece next to it. A piece named ``<side>HEE`` or ``<side>TOE`` and a piece
    that keeps the template heel-toe distance from it (within
    ``label_segment_tolerance_mm``, median over the fields both are seen) are the foot's
    two markers; the one ahead along the walk in most of those fields (:data:`FACING`)
    is the toe. Both are renamed when the names are free in their fields. Returns
    whether any piece was renamed.
    """
    tol = state.params.label_segment_tolerance_mm
    direction = walking_direction(state.name_pos)
    renamed = False
    for toe, heel in foot_pairs(state.names):
        length = state.template_distance[toe, heel]
        for p in np.flatnonzero(np.isin(state.label_of, (toe, heel))).tolist():
            if state.label_of[p] not in (toe, heel):
                continue  # renamed with an earlier piece
            f_p, x_p = state.piece(p)
            for q in _partners(state, p, f_p, x_p, length, tol):
                f_q, x_q = state.piece(q)
                shared, i_p, i_q = np.intersect1d(f_p, f_q, return_indices=True)
                ahead = np.sum((x_p[i_p, :2] - x_q[i_q, :2]) * direction[shared], axis=1)
                ahead = ahead[np.isfinite(ahead)]
                if ahead.size == 0:
                    continue
                p_is_toe = np.mean(ahead > 0) >= FACING
                if not (p_is_toe or np.mean(ahead < 0) >= FACING):
                    continue
                want_p, want_q = (toe, heel) if p_is_toe else (heel, toe)
                if (state.label_of[p], state.label_of[q]) == (want_p, want_q):
                    continue
                if _rename(state, (p, q), (want_p, want_q)):
                    renamed = True
                    break
    return renamed


def _partners(state: LabelState, p: int, f_p: NDArray, x_p: NDArray, length: float, tol: float):
    """Pieces (other than ``p``, named a foot name or unnamed) seen with piece ``p`` in
    at least three fields at the template's heel-toe ``length`` within ``tol``."""
    tracks = state.tracks
    rows = np.flatnonzero(np.isin(tracks.field, f_p) & (tracks.track != p))
    out = []
    for q in np.unique(tracks.track[rows]).tolist():
        f_q, x_q = state.piece(q)
        _, i_p, i_q = np.intersect1d(f_p, f_q, return_indices=True)
        if i_p.size < 3:
            continue
        d = np.linalg.norm(x_p[i_p] - x_q[i_q], axis=1)
        if abs(np.median(d) - length) <= tol:
            out.append(q)
    return out


def _rename(state: LabelState, pieces: tuple[int, int], names: tuple[int, int]) -> bool:
    """Give ``pieces`` the ``names`` when each name is held in its piece's fields by no
    piece but these two; returns whether it did."""
    old = [int(state.label_of[t]) for t in pieces]
    for t, j in zip(pieces, old, strict=True):
        if j >= 0:
            state.name_pos[j, state.piece(t)[0]] = np.nan
    free = all(
        not np.isfinite(state.name_pos[j, state.piece(t)[0], 0]).any()
        for t, j in zip(pieces, names, strict=True)
    )
    for t, j in zip(pieces, names if free else old, strict=True):
        if j >= 0:
            state.name_piece(t, j)
        else:
            state.label_of[t] = -1
    return free
