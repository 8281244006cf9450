"""Which of two window matches to keep: a body turned round never wins.

With few cameras the first window is often short, and its average pose can fit the
template as well turned round about the vertical (heels named toes, left named right,
the sacrum named an ASIS): such a body is proper (no mirror image), its distances nearly
the template's, and a few points added near a marker tip one way or the other. The
walk can tell: a subject walks forward, so toe markers lie ahead of heel markers, and
anterior pelvis markers ahead of posterior ones, along the direction the body moves
(lab Z up, as :mod:`~kisscal.tracking.labelling.anatomy` assumes).
:func:`facing` measures that for a match; :func:`better` keeps the match that faces
forward (``facing_fraction`` of the votes), else the one naming more pieces if it agrees
with the other's names.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.pelvis import PELVIS_BACK, PELVIS_FRONT
from kisscal.tracking.labelling.state import LabelState

#: The body moves at least this far (mm, horizontally) through a window for its
#: walking direction to count.
MIN_TRAVEL_MM = 100.0
#: Fewest names of a window match that can overrule another's (:func:`better`). A rigid
#: fit, the pose the names stand for, needs three points, but a triangle's three
#: distances are matched by chance among the template's many triangles (455 of 15
#: markers); four points' six distances are not. Kiss 3 cameras seed 434: the whole
#: trial held only three feet pieces whole; their triangle was named RASI, LKNE, LTIB,
#: and with the two broken as a segment, its one name RASI (a heel) overruled shorter
#: windows naming 11-13 pieces all right, and the trial got no name. Modern 3 cameras
#: seed 409: a long window's triangle (LASI, LTOE, RTIB named RASI, RANK, LTIB) vetoed
#: shorter windows naming 14 pieces right, and 13 of 15 names went wrong.
MIN_POSE_NAMES = 4
#: A heel marker name: its side prefix, then HEE, HEEL or CAL.
HEEL = re.compile(r"^(.*)(HEE|HEEL|CAL)$")


def foot_pairs(names: tuple[str, ...]) -> list[tuple[int, int]]:
    """(toe, heel) name pairs: ``<side>TOE`` and ``<side>HEE`` (or ``HEEL``, ``CAL``)."""
    index = {n: i for i, n in enumerate(names)}
    found = [(m.group(1) + "TOE", n) for n in names if (m := HEEL.match(n))]
    return [(index[toe], index[heel]) for toe, heel in found if toe in index]


def front_back_pairs(names: tuple[str, ...]) -> tuple[tuple[int, int], ...]:
    """(front, back) name pairs the naming convention gives: toes ahead of heels
    (:func:`foot_pairs`), each ``*ASI*`` ahead of each ``*PSI*`` or ``SACR``."""
    pairs = foot_pairs(names)
    front = [i for i, n in enumerate(names) if PELVIS_FRONT.search(n)]
    back = [i for i, n in enumerate(names) if PELVIS_BACK.search(n)]
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


def _side(value: float, fraction: float) -> int:
    """+1 facing forward, -1 turned round, 0 unknown (``facing_fraction``)."""
    if value >= fraction:
        return 1
    return -1 if value <= 1 - fraction else 0


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
    names, it does not overrule longer windows alone. A ``found`` naming fewer than
    :data:`MIN_POSE_NAMES` pieces holds no pose to agree with: any other naming more wins.
    """
    n_other = 0 if other.core is None else int(np.sum(other.assign >= 0))
    n_found = 0 if found.core is None else int(np.sum(found.assign >= 0))
    if n_found < MIN_POSE_NAMES or n_other == 0:
        return n_other > n_found
    fraction = state.params.facing_fraction
    a = _side(facing(state, found.core, found.assign, found.rich), fraction)
    b = _side(facing(state, other.core, other.assign, other.rich), fraction)
    if a != b and -1 in (a, b):
        return b > a
    return n_other > int(np.sum(found.assign >= 0)) and agrees(
        found.core, found.assign, other.core, other.assign
    )
