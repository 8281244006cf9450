"""The body's fills of a gap's run, as fills of :data:`~kisscal.tracking.fill_passes.FILLS`:
a spline for a short run, the body for a longer one (:func:`spline_or_body`), and the
segment carrying a track's end from its measured side (:func:`end_body`).

The candidates themselves are :mod:`kisscal.tracking.bodyfill`'s (and the hinge's,
:mod:`kisscal.tracking.fill_hinge`); here one is chosen for the run, moved onto the rays
of blobs a camera still sees there (:func:`~kisscal.tracking.fill_place.with_rays`), and
made to expect at least the errors of what it reads (:mod:`kisscal.tracking.fill_anchor`,
:mod:`kisscal.tracking.fill_spline`).

References
----------
Challis 1995 (segments as rigid bodies of markers); Gløersen & Federolf 2016 (gap
filling from the other markers of the body).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.blob_paths import parted
from kisscal.tracking.bodyfill import best_candidate, fill_candidates
from kisscal.tracking.fill_anchor import anchored, body_donors, donor_errors, donor_noise
from kisscal.tracking.fill_ends import end_carriers, end_reach, one_sided
from kisscal.tracking.fill_hinge import HINGE_METHODS
from kisscal.tracking.fill_place import at_least, placed_mask, with_rays
from kisscal.tracking.fill_spline import context_noise, sight_noise, spline_fill, unpulled
from kisscal.tracking.fill_table import hole_length
from kisscal.tracking.gap_record import Gap
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import FILLED, FILLED_RIGID


def spline_or_body(
    gap: Gap, a: int, b: int, params: TrackingParams, spline: bool = True, checked: bool = False
) -> NDArray[np.bool_]:
    """Spline for short runs (unless not ``spline``), the body (:func:`best_candidate`)
    for longer ones, as a fill of :data:`~.fill_passes.FILLS` expecting at least the
    error of the gap's fills it reads (:func:`anchored`); with spare blobs, each filled
    field a camera still sees moved onto its ray (:func:`with_rays`); no spline where the
    marker's blobs followed in the image from the two sides part
    (:func:`~kisscal.tracking.blob_paths.parted`).
    A spline expects at least what the noise of the samples it goes through carries
    (:func:`~kisscal.tracking.fill_spline.context_noise`; lowcost 301-313: 98 samples over
    twice their spline's expected error, the stretches it is tried on quieter); moved
    onto a ray, what of that noise lies along the sight of the cameras whose blobs it
    looked for (:func:`~kisscal.tracking.fill_spline.sight_noise`). With
    ``checked``, a spline is kept only when, counting the largest expected error of the
    samples it reads too (``gap.errors``), it expects at most ``max_body_fill_error_mm``
    (else the body: kiss 3 seed 303's toe, 5 fields beside a chain fill, left open)."""
    none = np.zeros(b - a, dtype=bool)
    hole = hole_length(gap.dense[gap.t], a, b)  # what a spline bridges, not the run alone
    short = (spline or checked) and hole <= params.max_fill_gap_fields
    if not short and b - a > params.max_body_fill_fields:
        return none
    spare = gap.spare
    rays = spare is not None and spare.rows(a, b).size > 0
    methods = ((FILLED, spline_fill),) if short else HINGE_METHODS
    centres = spare.centres if rays else None
    body = body_donors(gap, params)
    if short and rays:  # a spline with blobs in its gap
        body = unpulled(body, gap, a, b, params)
    cands = fill_candidates(body, gap.t, a, b, params, methods, centres)
    chosen = cands[0] if short and cands else best_candidate(cands, params)
    # a spline has no error of its own to check: between samples the marker's own image
    # does not join, it may bridge to another marker's
    if chosen is None or (short and rays and parted(gap.dense[gap.t], a, b, spare, params)):
        return spline_or_body(gap, a, b, params, spline=False) if checked and short else none
    seen = spare.centres[np.unique(spare.camera[spare.rows(a, b)])] if rays else None
    got = with_rays(chosen, spare, params) if rays else [(chosen.xyz_mm, chosen.fill)]
    if short:  # after the rays (their gate is the stretches' error): through noisy samples
        n = max(params.fill_context_fields, 2)
        noise = context_noise(body[gap.t], None, a, b, n)
        along = sight_noise(body[gap.t], seen, a, b, n) if rays else noise
        got = [(x, at_least(f, along if f.ray_fields else noise)) for x, f in got]
        if checked:
            near = gap.errors[gap.t, max(a - n, 0) : b + n] if gap.errors is not None else []
            got = [(x, at_least(f, float(np.nanmax(np.r_[near, 0.0])))) for x, f in got]
            worst = np.max([f.expected_error_mm for _, f in got] or [np.inf])
            if not worst <= params.max_body_fill_error_mm:  # NaN: nothing to check it by
                return spline_or_body(gap, a, b, params, spline=False)  # the body, as without
    got = donor_errors(donor_noise(got, gap.dense), gap.errors)
    gap.out.extend(anchored(got, gap.out, params.fill_context_fields))
    return placed_mask(got, a, b)


def end_body(gap: Gap, a: int, b: int, params: TrackingParams) -> NDArray[np.bool_]:
    """The fields of the end [a, b) of a track next to its measured samples that its
    segment carries (:mod:`kisscal.tracking.fill_ends`): as far as all its donors are
    measured, by them or by its two most rigid markers; then as far as those two are,
    by them; each kept when its expected error is at most ``max_body_fill_error_mm``,
    moved onto the rays of blobs a camera still sees there (:func:`with_rays`) and
    written into ``gap.dense`` (the edge the one-camera fill beyond walks from)."""
    placed = np.zeros(b - a, dtype=bool)
    after = gap.end < 0
    rigid, axis = (FILLED_RIGID, one_sided(after)), (FILLED_RIGID, one_sided(after, axis=True))
    done, donors = 0, None
    for k, methods in ((params.rigid_fill_markers, (rigid, axis)), (2, (axis,))):
        if donors is None:  # chosen again once a fill has changed the trial
            donors = end_carriers(gap.dense, gap.t, a, b, after, params)
        n = end_reach(gap.dense, donors[:k], a, b, after)
        if n <= done:
            continue
        lo, hi = (b - n, b - done) if after else (a + done, a + n)
        rays = gap.spare is not None and gap.spare.rows(lo, hi).size > 0
        centres = gap.spare.centres if rays else None
        cands = fill_candidates(body_donors(gap, params), gap.t, lo, hi, params, methods, centres)
        chosen = best_candidate(cands, params)
        if chosen is None:
            break
        got = with_rays(chosen, gap.spare, params) if rays else [(chosen.xyz_mm, chosen.fill)]
        gap.out.extend(donor_errors(donor_noise(got, gap.dense), gap.errors))
        placed[lo - a : hi - a] = mine = placed_mask(got, lo, hi, gap.dense[gap.t])
        if not mine.all():
            break  # its rays refused part of it: what lies beyond has no edge to walk from
        done, donors = n, None
    return placed
