"""Phase 5b: a name the trial never showed, given to the one piece that fits it.

With three cameras a marker may be seen by two of them for only a stretch as short as
``min_track_length`` (kiss 3-camera seed 304: the right thigh for 15 fields at the end of
the walk, the right knee and ankle never, the pelvis out of view). Its piece has no
rigid partner held, so spreading's segments (:mod:`.spread`) cannot name it; the body
fit from its nearest named markers (the other leg's) misses it by a stride; and its
name has no trajectory, so the trial's own distances (:mod:`.learned`) say nothing
about it. What remains is the template: the piece's distances to the names held in its
fields against each name's template distances to them. Those change as the subject
walks, more the longer the chain of joints between two markers, so a misfit is counted
in spreads of :data:`SPREAD_FLOOR_MM` plus :data:`RELATIVE_SPREAD` of the template
distance, per held name RMS over the fields and capped as in :mod:`.learned`. Every
name of the set competes, held ones too (a late piece of the left ASIS fits the left
ASIS, not a free name), and the piece takes a name only when that name is held nowhere
in the trial, fits within :data:`MAX_FIT` from at least :data:`~.learned.MIN_PARTNERS`
held names, and beats every other name by :data:`MARGIN`; otherwise it stays unnamed
and is reported (``M<k>``).
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.learned import LONG_PIECE, trial_scores
from kisscal.tracking.labelling.spread import body_fit_distances
from kisscal.tracking.labelling.state import (
    CLEAR_RATIO,
    LONE_NAME_REACH,
    MIN_SHARED_FIELDS,
    RIGID_SPREAD_MM,
    LabelState,
)

#: Floor (mm) of a template distance's spread: the piece's own noise and the subject's
#: build against the template's.
SPREAD_FLOOR_MM = 15.0
#: Part of a template distance by which it may change while the subject walks (a
#: segment swinging through about 6 degrees, as an SD, about a joint between the markers).
RELATIVE_SPREAD = 0.1
#: Largest misfit (mean squared spreads) of the name given: the right name's, over ten
#: held names, stays below it 19 times in 20 (chi-squared).
MAX_FIT = 2.0
#: The runner-up's misfit must exceed the best name's by this much (mean squared
#: spreads; over k held names a likelihood ratio of exp(0.75 k) for the best): the
#: other side's name (the left thigh for the right one) differs from it in the few
#: distances to the near markers only, so :data:`~.learned.MARGIN` (3) is out of reach
#: for it with spreads this wide.
MARGIN = 1.5


def template_scores(state: LabelState, t: int) -> NDArray[np.float64]:
    """Misfit (mean squared spreads, capped per held name at
    :data:`~.learned.MAX_PAIR_SCORE`) of piece ``t``'s distances to the names held in its
    fields against every name's template distances to them; inf with fewer than
    :data:`~.learned.MIN_PARTNERS` held names."""
    template = state.template_distance  # (J, n): every name against every held one
    spread = SPREAD_FLOOR_MM + RELATIVE_SPREAD * template
    # a name is not its own partner: its column says where it is held, not how far
    np.fill_diagonal(spread, np.nan)
    return trial_scores(state, t, np.arange(len(template)), template, spread)


def name_unseen(state: LabelState) -> bool:
    """Phase 5b (see module): unnamed pieces of at least ``min_track_length`` measured
    samples, longest first, take the never-held name whose template distances they keep
    clearly best. Returns whether any piece was named."""
    waiting = np.flatnonzero(
        (state.label_of < 0) & (state.n_measured >= state.params.min_track_length)
    )
    named = False
    for t in waiting[np.argsort(-state.n_measured[waiting], kind="stable")].tolist():
        unseen = ~np.isfinite(state.name_pos[..., 0]).any(axis=1)
        if not unseen.any():
            break
        score = template_scores(state, t)
        order = np.argsort(score)
        best, second = score[order[0]], score[order[1]]
        if unseen[order[0]] and best <= MAX_FIT and second - best >= MARGIN:
            state.name_piece(t, int(order[0]))
            named = True
    return named


def segment_claims(state: LabelState) -> dict[int, list[int]]:
    """Per name never held, the unnamed pieces that claim it: a piece of at least
    :data:`~.learned.LONG_PIECE` times ``min_track_length`` measured samples keeps its
    distance (SD under the rigid spread) to a named marker through half of its fields
    and :data:`~.state.MIN_SHARED_FIELDS` at least (a few fields beside any marker look
    rigid), and of the names of the set's segments that such markers hold, exactly one
    is never held."""
    unseen = ~np.isfinite(state.name_pos[..., 0]).any(axis=1)
    long = state.n_measured >= LONG_PIECE * state.params.min_track_length
    waiting = np.flatnonzero((state.label_of < 0) & long)
    claims: dict[int, list[int]] = {}
    if state.given_rigid is None or not unseen.any():
        return claims
    for t in waiting.tolist():
        fields, xyz = state.piece(t)
        d = np.linalg.norm(state.name_pos[:, fields] - xyz[None], axis=2)  # (n, F)
        shared = np.isfinite(d).sum(axis=1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # names never seen with it
            rigid = (np.nanstd(d, axis=1) < RIGID_SPREAD_MM) & (
                shared >= max(MIN_SHARED_FIELDS, fields.size / 2)
            )
        names = np.flatnonzero(state.given_rigid[rigid].any(axis=0) & unseen)
        if names.size == 1:
            claims.setdefault(int(names[0]), []).append(t)
    return claims


def name_by_segment(state: LabelState) -> bool:
    """Pieces rigid with a segment whose other name the trial never showed take it (see
    module): one piece claims it (:func:`segment_claims`), and the body fit
    (:func:`~.spread.body_fit_distances`, median) puts it within
    :data:`~.state.LONE_NAME_REACH` label tolerances and every other free name
    :data:`~.state.CLEAR_RATIO` times farther: the
    marker sits off the template's place, but the other side's name or another limb's
    lies farther still. Returns whether any piece was named.

    References
    ----------
    Shafiq et al. 2001 (rigid segment lengths as a check on a marker's identity).
    """
    named = False
    tolerance = state.params.label_tolerance_mm
    for j, pieces in segment_claims(state).items():
        if len(pieces) != 1:
            continue  # two markers rigid with the segment: another set's beside it
        fields, xyz = state.piece(pieces[0])
        free = np.flatnonzero(~np.isfinite(state.name_pos[:, fields, 0]).any(axis=1))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # fields without 3 names
            dist = np.nanmedian(
                body_fit_distances(fields, xyz, free, state.name_pos, state.template), axis=0
            )
        own = dist[free == j][0]
        others = dist[free != j]
        if own <= LONE_NAME_REACH * tolerance and not (others < CLEAR_RATIO * own).any():
            state.name_piece(pieces[0], j)
            named = True
    return named
