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

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.learned import trial_scores
from kisscal.tracking.labelling.state import LabelState

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
