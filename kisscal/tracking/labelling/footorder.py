"""A foot's heel and toe names judged by their order along the walk.

The markers of a foot stay rigid to each other whatever names they are given, so the
set's segments cannot tell a foot named one marker along (issue 26: a child's right foot
tracked in other pieces took the heel's name on the ankle marker and the ankle's on a
piece of the toe marker, the heel marker left unnamed) from a foot named right. The walk
can: a heel marker sits on the back of the calcaneus, the rearmost point of the foot, and
a toe marker on the forefoot, its foremost, and the foot's pitch in gait (about 20 degrees
toe up at heel strike, 50 heel up at toe off) never turns that order along the direction
the subject faces (Perry & Burnfield 2010). So a trajectory rigid to the heel's name and
near it that lies behind it along the subject's forward direction means the heel's name
is on another marker of the foot, and likewise one ahead of the toe's name. It must lie
beyond by more than half the template's gap from that end to the foot's next name (the
ankle's, or the other end's) along the foot: a name shifted one marker along leaves the
end's own marker a whole gap beyond it, while a set's foreign forefoot marker may lie a
little ahead of the toe marker (walking5's first metatarsal head, 21 mm ahead of the
second's, which takes the toe's name).
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray

from kisscal.markersets.model import MarkerSet
from kisscal.tracking.labelling.anatomy import Anatomy, forward_directions
from kisscal.tracking.labelling.facing import HEEL, foot_pairs
from kisscal.tracking.labelling.partial import VOUCH_SPREAD_MM, named_positions, unnamed_positions
from kisscal.tracking.labelling.result import Labelling
from kisscal.tracking.labelling.state import MIN_SHARED_FIELDS, RIGID_SPREAD_MM

#: A rigid neighbour must lie at least this far (mm, median along the forward direction)
#: behind a heel's name, or ahead of a toe's, to doubt it, whatever the template's gap:
#: three rigid spreads, above the markers' skin motion.
BEYOND_MM = 3.0 * RIGID_SPREAD_MM
#: ... and beyond this fraction of the template's gap from the end to the foot's next
#: name along the foot (see module).
GAP_FRACTION = 0.5
#: Forward directions that this module trusts: the walk, or the pelvis' facing; never the
#: feet's own heel-to-toe direction, which the names being judged give.
_SOURCES = ("walking", "pelvis")


def _beyond(one: NDArray, others: NDArray, forward: NDArray, reach_mm: float) -> NDArray:
    """Median offset (mm) along ``forward`` (F, 2) of each of ``others`` (m, F, 3) from
    ``one`` (F, 3), NaN for those not rigid to it (distance SD at or over
    :data:`VOUCH_SPREAD_MM`), not near it (median distance over ``reach_mm``) or seen with
    it in fewer than :data:`MIN_SHARED_FIELDS` or half of its fields."""
    gap = others - one[None]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # pieces never seen with it
        d = np.linalg.norm(gap, axis=2)
        along = np.sum(gap[..., :2] * forward[None], axis=2)
        along[~np.isfinite(d)] = np.nan
        sd, dist, offset = np.nanstd(d, axis=1), np.nanmedian(d, axis=1), np.nanmedian(along, 1)
    shared = np.isfinite(along).sum(axis=1)
    enough = max(MIN_SHARED_FIELDS, int(np.isfinite(one[:, 0]).sum()) // 2)
    ok = (shared >= enough) & (sd < VOUCH_SPREAD_MM) & (dist <= reach_mm)
    return np.where(ok, offset, np.nan)


def _ends(
    names: tuple[str, ...], template: NDArray, toe: int, heel: int
) -> list[tuple[int, float, float]]:
    """(row, sign, margin mm) of a foot's heel (behind: -1) and toe (ahead: +1): the
    margin is :data:`GAP_FRACTION` of the template's gap, along the heel-to-toe axis, to
    the foot's next name (the ankle, ``<side>ANK``, when the set has one), at least
    :data:`BEYOND_MM`."""
    axis = template[toe] - template[heel]
    axis = axis / np.linalg.norm(axis)
    ankle = f"{HEEL.match(names[heel]).group(1)}ANK"
    back = front = names.index(ankle) if ankle in names else None
    back, front = (toe, heel) if back is None else (back, front)
    gap_heel = float((template[back] - template[heel]) @ axis)
    gap_toe = float((template[toe] - template[front]) @ axis)
    return [
        (heel, -1.0, max(BEYOND_MM, GAP_FRACTION * gap_heel)),
        (toe, 1.0, max(BEYOND_MM, GAP_FRACTION * gap_toe)),
    ]


def out_of_order_feet(
    labelling: Labelling, marker_set: MarkerSet, anatomy: Anatomy, rate_hz: float
) -> tuple[str, ...]:
    """Heel and toe names of ``labelling`` with a rigid neighbour beyond them on the foot.

    Parameters
    ----------
    labelling : Labelling
        Named with ``marker_set``.
    marker_set : MarkerSet
        The set, its template scaled to the subject (the foot's length bounds "near").
    anatomy : Anatomy
        Of ``marker_set`` (the pelvis' front and back, for the forward direction).
    rate_hz : float

    Returns
    -------
    tuple of str
        Each ``<side>HEE`` (``HEEL``, ``CAL``) name with a trajectory (named or not) rigid
        to it and within the foot's heel-to-toe length that lies more than
        :data:`BEYOND_MM` behind it along the subject's forward direction (the walk's, or
        the pelvis' facing), and each ``<side>TOE`` name with one as far ahead of it.
        Nothing when the forward direction is unknown.

    References
    ----------
    Perry & Burnfield 2010 (the foot's pitch through the gait cycle); Davis et al. 1991
    (the heel and toe markers of the conventional gait model).
    """
    names = marker_set.names
    pos = named_positions(labelling, names)
    forward, source = forward_directions(pos, anatomy, rate_hz)
    if source not in _SOURCES:
        return ()
    others = unnamed_positions(labelling)
    template = marker_set.template_mm
    doubted = set()
    for toe, heel in foot_pairs(names):
        reach = float(np.linalg.norm(template[toe] - template[heel]))
        for row, sign, margin in _ends(names, template, toe, heel):
            if not np.isfinite(pos[row, :, 0]).any():
                continue
            rest = np.concatenate([others, np.delete(pos, row, axis=0)])
            offset = _beyond(pos[row], rest, forward, reach)
            with np.errstate(invalid="ignore"):
                if np.any(sign * offset > margin):
                    doubted.add(names[row])
    return tuple(n for n in names if n in doubted)
