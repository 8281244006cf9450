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
A marker whose name no trajectory holds has no such distances and is never named here;
nor is a piece near the body that the trial never showed as a marker of the set (its
distances do not keep any name's).
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray

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
    return named
