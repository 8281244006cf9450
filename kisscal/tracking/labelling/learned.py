"""Phase 5: long pieces with no named rigid partner in their fields, named from the
body as the trial itself shows it.

With three cameras a marker may come back late in the trial, when the other markers of
its segment are out of sight (a toe after its heel has gone, a shank marker whose knee
and ankle are never measured): spreading (:mod:`.spread`) has no partner to go by, and
the body fit (a standing template placed on the named markers around) is off by a
stride when the nearest named markers are on the other leg. But every name given so far
has a trajectory, and between two trajectories the trial shows how far apart the two
markers are and how much that varies while the subject walks (a heel from the sacrum:
about a metre, give or take a few centimetres; from the other foot: anything within a
stride). So a long unnamed piece (:data:`LONG_PIECE`) takes the free name (held in none
of its fields, named elsewhere in the trial) whose distances to the names held in its
fields it keeps as the trial does: within :data:`MAX_SCORE` spreads (:func:`trial_scores`),
from at least :data:`MIN_PARTNERS` names, and clearly better than any other name the
trial showed, held ones included (:data:`MARGIN`): a heel and a toe keep nearly the same
distances to the rest of the body, so a heel piece whose own name a track holds wrongly
would otherwise take the free toe name (kiss 3-camera seed 312).
That near tie between one foot's heel and toe, with every other name far worse, the walk
settles when another piece is seen with this one at the template's heel-to-toe length:
the one behind along the direction the body moves is the heel (:func:`foot_end`; kiss 3
seed 421: a left foot's heel and toe pieces over its first two strides, its ankle and
knee never seen, its names held only from its third). A piece with no such partner
stays unnamed: the path it continues is no help while the foot's contest
(:func:`~kisscal.tracking.labelling.feet.settle_feet`) may still exchange the two names'
trajectories (kiss 3 seed 402: a toe piece so named moved with them to the heel).
A marker whose name no trajectory holds has no such distances and is never named here;
nor is a piece near the body that the trial never showed as a marker of the set (its
distances do not keep any name's).
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.facing import foot_pairs
from kisscal.tracking.labelling.pelvis import walking_direction
from kisscal.tracking.labelling.state import MIN_SHARED_FIELDS, LabelState

#: Floor (mm) of the spread of a distance: two markers of one segment keep their distance
#: within a millimetre or two, but the piece's own samples are noisier than that.
SPREAD_FLOOR_MM = 10.0
#: A name's misfit to one held name counts at most this many spreads: a pair the trial
#: showed only in part of the stride (a spread too small) does not decide alone.
MAX_PAIR_SCORE = 4.0
#: Largest misfit, in spreads, of a piece's distances to the names around it.
MAX_SCORE = 2.5
#: The runner-up's misfit (mean squared spreads) must exceed the best name's by this
#: much: over k held names, a likelihood ratio of exp(k * MARGIN / 2) for the best.
MARGIN = 3.0
#: Pieces at least this many times ``min_track_length`` are named here: over fewer
#: fields a piece of the other side's marker can keep a name's distances as well as its
#: own (lowcost 302 and 303: right ASIS pieces of 11 and 16 fields fit the left ASIS's
#: distances better than the right one's, at the end of the walk).
LONG_PIECE = 2
#: Fewest names held in the piece's fields that the distances are taken to.
MIN_PARTNERS = 3


def distance_statistics(name_pos: NDArray, rows: NDArray | None = None) -> tuple[NDArray, NDArray]:
    """Median and spread (SD, floored at :data:`SPREAD_FLOOR_MM`) of the distance between
    every two named trajectories over the fields where both are held (NaN when they
    share fewer than :data:`MIN_SHARED_FIELDS`); with ``rows``, only from those names
    (the other rows NaN)."""
    seen = np.isfinite(name_pos[..., 0])
    held = np.flatnonzero(seen.any(axis=1))
    rows = held if rows is None else np.intersect1d(rows, held)
    n = name_pos.shape[0]
    median = np.full((n, n), np.nan)
    spread = np.full((n, n), np.nan)
    if held.size < 2 or rows.size == 0:
        return median, spread
    fields = np.flatnonzero(seen[held].sum(axis=0) >= 2)
    pos = name_pos[np.ix_(held, fields)]
    d = np.linalg.norm(name_pos[np.ix_(rows, fields)][:, None] - pos[None], axis=3)  # (r, h, F)
    shared = np.isfinite(d).sum(axis=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # pairs never seen together
        m = np.nanmedian(d, axis=2)
        s = np.maximum(np.nanstd(d, axis=2), SPREAD_FLOOR_MM)
    few = shared < MIN_SHARED_FIELDS
    m[few] = s[few] = np.nan
    median[np.ix_(rows, held)], spread[np.ix_(rows, held)] = m, s
    np.fill_diagonal(median, np.nan)
    return median, spread


def trial_scores(
    state: LabelState, t: int, free: NDArray, median: NDArray, spread: NDArray
) -> NDArray[np.float64]:
    """Misfit (mean squared spreads) of piece ``t``'s distances to the names held in its
    fields against each free name's distances to them in the trial: per held name the
    RMS over the fields, capped at :data:`MAX_PAIR_SCORE`, squared and averaged over the
    names; inf with fewer than :data:`MIN_PARTNERS` names."""
    fields, xyz = state.piece(t)
    d = np.linalg.norm(state.name_pos[:, fields] - xyz[None], axis=2)  # (n, F)
    z = (d[None] - median[free][:, :, None]) / spread[free][:, :, None]  # (J, n, F)
    ok = np.isfinite(z)
    count = ok.sum(axis=2)
    with np.errstate(invalid="ignore", divide="ignore"):
        per_name = np.sqrt(np.where(ok, z * z, 0.0).sum(axis=2) / count)  # (J, n)
    per_name[count == 0] = np.nan
    partners = (count > 0).sum(axis=1)
    capped = np.minimum(np.nan_to_num(per_name, nan=0.0), MAX_PAIR_SCORE)
    with np.errstate(invalid="ignore", divide="ignore"):
        score = (capped**2).sum(axis=1) / partners
    return np.where(partners >= MIN_PARTNERS, score, np.inf)


def foot_end(state: LabelState, t: int, toe: int, heel: int, direction: NDArray) -> int | None:
    """Of one foot's ``toe`` and ``heel`` names, the one piece ``t`` takes by the walk:
    every other piece (named or not) seen with it in :data:`MIN_SHARED_FIELDS` fields at the
    template's heel-to-toe length (RMS within ``label_segment_tolerance_mm``) lies behind it
    along ``direction`` (F, 2) in ``facing_fraction`` of those fields (``t`` is the toe), or
    each ahead of it (the heel); None with no such piece or when they disagree (Perry &
    Burnfield 2010: the foot's pitch in gait never turns that order)."""
    params = state.params
    fields, xyz = state.piece(t)
    length = state.template_distance[toe, heel]
    verdicts = set()
    for u in np.flatnonzero(state.n_measured >= MIN_SHARED_FIELDS).tolist():
        if u == t:
            continue
        pos = np.full_like(xyz, np.nan)
        f, x = state.piece(u)
        at = np.searchsorted(fields, f)
        inside = (at < fields.size) & (fields[np.minimum(at, fields.size - 1)] == f)
        pos[at[inside]] = x[inside]
        miss = np.linalg.norm(pos - xyz, axis=1) - length
        miss = miss[np.isfinite(miss)]
        if miss.size < MIN_SHARED_FIELDS or np.sqrt(np.mean(miss**2)) > (
            params.label_segment_tolerance_mm
        ):
            continue
        if state.label_of[u] >= 0 and state.label_of[u] not in (toe, heel):
            return None  # rigid to another name at the foot's length: not this foot's end
        # the other piece's offset along the walk (feet.trailing, which imports this module)
        votes = np.sum((pos - xyz)[:, :2] * direction[fields], axis=1)
        votes = votes[np.isfinite(votes)]
        frac = params.facing_fraction * max(votes.size, 1)
        verdicts.add(
            toe if (votes < 0).sum() >= frac else heel if (votes > 0).sum() >= frac else -1
        )
    return verdicts.pop() if len(verdicts) == 1 and -1 not in verdicts else None


def name_from_trial(state: LabelState) -> bool:
    """Phase 5 (see module): long unnamed pieces, longest first, take the free name whose
    trial distances they keep. Returns whether any piece was named."""
    params = state.params
    long = state.n_measured >= LONG_PIECE * params.min_track_length
    waiting = np.flatnonzero((state.label_of < 0) & long)
    if waiting.size == 0:
        return False
    waiting = waiting[np.argsort(-state.n_measured[waiting], kind="stable")]
    median, spread = distance_statistics(state.name_pos)
    known = np.flatnonzero(np.isfinite(median).any(axis=1))
    feet = {frozenset(p): p for p in foot_pairs(state.names)}
    direction = walking_direction(state.name_pos)
    named = False
    for t in waiting.tolist():
        fields, _ = state.piece(t)
        is_free = ~np.isfinite(state.name_pos[known][:, fields, 0]).any(axis=1)
        if not is_free.any():
            continue
        # every name the trial showed competes, held ones too: a heel piece whose own
        # name is held by a track that carries it wrongly fits the free toe name almost as
        # well as its own, and must then stay unnamed (kiss3 312)
        score = trial_scores(state, t, known, median, spread)
        order = np.argsort(score)
        best = score[order[0]]
        second = score[order[1]] if order.size > 1 else np.inf
        if is_free[order[0]] and best <= MAX_SCORE**2 and second - best >= MARGIN:
            state.name_piece(t, int(known[order[0]]))
            named = True
            continue
        # a heel and a toe keep alike distances to the rest of the body: the walk decides
        pair = frozenset(known[order[:2]].tolist())
        third = score[order[2]] if order.size > 2 else np.inf
        if pair in feet and second <= MAX_SCORE**2 and third - second >= MARGIN:
            j = foot_end(state, t, *feet[pair], direction)
            if j is not None and is_free[np.flatnonzero(known == j)[0]]:
                state.name_piece(t, j)
                named = True
    return named
