"""Body fill of what every other fill left, through donors that are fills themselves,
their error counted.

The body fills follow only donors measured or filled expecting at most
``ray_rest_max_error_mm`` (:func:`~.fill_anchor.body_donors`): a donor that is a poor fill
in the gap carries the marker off unseen, since the fill's own error is measured beside
the gap, where its donors are measured (kiss 3 seed 412). Yet where no camera sees a
marker and one of its segment's mates is itself a fill expecting a little more, the gap
stays open though the segment carries it well (modern 3 seed 446: LANK hidden from all
three cameras for 40 fields, LTIB a fill expecting 3.3 mm there; with LKNE, a rigid
fill 1.0 mm RMS off expecting 0.5 from the stretches). So, last, once every other fill
is made, the body's rigid fills are tried again with donors filled expecting up to
``max_body_fill_error_mm``, each candidate expecting at least the largest error of its
donors' samples in the gap (:func:`~.fill_anchor.donor_errors`), and kept when that is
at most ``max_body_fill_error_mm``: a fill that says honestly how far off it may be.
Only candidates the body's fills could not make (:func:`over_bar`): those that follow
such a donor, or one of the samples only this pass has as context (below; modern 3 seed
470: RHEE hidden from all three cameras for 44 fields, RANK and RTOE each a spline on
its rays in the gap's first field, the hinge about them 0.6 mm RMS off), or that expect
over ``ray_rest_max_error_mm`` themselves, the bar of the body's fills between fields
placed on rays and in the second passes; the others they refused for reasons of their
own (lowcost 322 RHEE from RANK and RTOE, 5.2 mm off
expecting 1.4). And only in the fields where no camera sees the marker (:func:`unseen`):
where one does, the fills on its own rays had their say and left it, and a donor fill
there is no better checked than they were (kiss 3 seed 412: RANK through RTOE, a chain
fill 11.7 mm RMS off expecting 4.0, moved onto RANK's rays 11.1 mm off expecting 4.0).

Its donors are the second passes' context and, here, every fill placed on a camera's rays
in all its fields expecting at most ``max_body_fill_error_mm`` (:func:`context`): a
segment mate's spline moved onto its rays is not context before (a spline through a
mate's wrong samples carries the marker onto them), and a mate missing one field of the
gap is no donor through it (modern 3 seed 408: LTOE hidden from all three cameras for
76 fields, LANK and LHEE seen by two in all but one of them, where their splines on
their rays expect 0.6 mm; with them the two-marker fill, 4.2 mm RMS off, the toe's
coverage 68.6 -> 100 %).

A marker on two segments (an ankle, which keeps its distance to the shank and to the
foot) may get no donors at all: the body's fills start from the marker most rigid to it
(the tibia), which rules out the other segment's (heel and toe), and with the knee lost
the tibia alone carries nothing (modern 3 seed 430: RANK hidden from all three cameras
for 41 fields). So here the fills are also made through the largest group of markers
rigid to it and to each other (:func:`widest_segment`), where that is not the most rigid
marker's: donors the body's fills did not choose, so not held to :func:`over_bar`. Only
here: chosen so in every pass, a heel's end fill from the toe and ankle expected 1.2 mm
and was 3.8 mm off (kiss 3 seed 301).

References
----------
Challis 1995 (segments as rigid bodies of markers); Gløersen & Federolf 2016 (gap
filling from the other markers of the body).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import true_runs
from kisscal.tracking.bodyfill import (
    Candidate,
    GapFill,
    axis_fill,
    distance_sd,
    fill_candidates,
)
from kisscal.tracking.fill_anchor import anchored, donor_errors, donor_noise, trusted
from kisscal.tracking.fill_centre import trusted_centre_body
from kisscal.tracking.fill_hinge import HINGE_METHODS
from kisscal.tracking.fill_hip import trusted_hip
from kisscal.tracking.fill_place import mirror_checked, placed_mask
from kisscal.tracking.fill_table import Fill
from kisscal.tracking.gap_record import Gap
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs, ray_correct
from kisscal.tracking.tracks import FILLED_RIGID

#: The body's fills that carry the marker with its segment
#: (:data:`~.fill_hinge.HINGE_METHODS` but the pattern fill): a pattern fill follows one
#: neighbour whose offset may stray in the gap (lowcost 410 LTHI following LKNE, 10 mm
#: RMS off expecting 5.0).
RIGID_METHODS = tuple(m for m in HINGE_METHODS if m[0] == FILLED_RIGID)

#: :data:`RIGID_METHODS` that find the segment's turn in the trial (all but the two-marker
#: fill, :func:`~.bodyfill.axis_fill`, which holds it against a lab direction): the ones
#: made through donors only this pass has (:func:`over_bar`'s ``borrowed``). A fill the
#: passes before never tried has not been checked by them either, and a foot rolls about
#: its axis (modern 3 seed 408: LTOE by the two-marker fill from LHEE and LANK, 4.2 mm
#: RMS off expecting 2.5; the hinge taken before, 3.0 off expecting 3.9).
TURNING_METHODS = tuple(m for m in RIGID_METHODS if m[1] is not axis_fill)


def counted(cands: list[Candidate], errors: NDArray) -> list[Candidate]:
    """``cands`` each expecting at least the largest expected error of its donors'
    samples over its fields (``errors``, (>= n_tracks, n_fields), NaN where none); those
    whose own error could not be measured (NaN) left out: their donors' errors do not
    measure them (kiss 3 seed 430: LANK's two-marker fill from LTOE and LHEE, 4.4 mm
    RMS off, expected 1.6 from LHEE's spline fill of one field)."""
    cands = [c for c in cands if np.isfinite(c.fill.expected_error_mm)]
    got = donor_errors([(c.xyz_mm, c.fill) for c in cands], errors)
    return [dataclasses.replace(c, fill=f) for c, (_, f) in zip(cands, got, strict=True)]


def best_counted(
    cands: list[Candidate], errors: NDArray, params: TrackingParams
) -> Candidate | None:
    """The candidate of ``cands`` of least expected error with its donors' errors counted
    (:func:`counted`), at most ``max_body_fill_error_mm``; among equals, the one of least
    error of its own: where one donor's error stands for every candidate's, the least
    does not tell them apart (modern 3 seed 470: RHEE from RANK and RTOE, all expecting
    RTOE's 2.2 mm, the rigid fill through the shank 4.9 mm RMS off taken before the hinge
    about RANK-RTOE expecting 0.7 mm of its own, 0.6 off)."""
    mine = [c for c in cands if np.isfinite(c.fill.expected_error_mm)]
    limit = params.max_body_fill_error_mm
    ok = [
        (c, own)
        for c, own in zip(counted(mine, errors), mine, strict=True)
        if c.fill.expected_error_mm <= limit
    ]
    if not ok:
        return None
    return min(ok, key=lambda p: (p[0].fill.expected_error_mm, p[1].fill.expected_error_mm))[0]


def over_bar(
    cands: list[Candidate], errors: NDArray, bar: float, borrowed: NDArray | None = None
) -> list[Candidate]:
    """``cands`` that follow a donor filled expecting over ``bar`` (mm) in the fields
    they fill (``errors``, (>= n_tracks, n_fields), NaN where none), or one ``borrowed``
    there ((n_tracks, n_fields) bool, :attr:`~.gap_record.Gap.borrowed`: a sample the
    passes before did not have), or that expect over ``bar`` themselves: the ones the
    body's fills could not make. The others they refused for reasons of their own."""
    out = []
    for c in cands:
        span = slice(c.fill.first_field, c.fill.first_field + c.fill.n_fields)
        rows = errors[list(c.fill.donors), span]
        new = borrowed is not None and bool(borrowed[list(c.fill.donors), span].any())
        with np.errstate(invalid="ignore"):
            if new or np.any(rows > bar) or c.fill.expected_error_mm > bar:
                out.append(c)
    return out


def context(fill: GapFill, params: TrackingParams, trusting: bool) -> bool:
    """Whether ``fill`` is context for the fills of a second pass (written into its
    positions, :func:`~kisscal.tracking.fill_runner.second_pass`): a rigid or ray fill
    (``filled_rigid``) expecting at most ``ray_rest_max_error_mm``; with ``trusting``
    (:data:`TRUSTED_PASS`, whose fills count their donors' errors), also any fill placed
    on a camera's rays in all its fields expecting at most ``max_body_fill_error_mm``
    (see module)."""
    if trusting and 0 < fill.ray_fields == fill.n_fields:
        return bool(fill.expected_error_mm <= params.max_body_fill_error_mm)
    bar = params.ray_rest_max_error_mm
    return bool(fill.status == FILLED_RIGID and fill.expected_error_mm <= bar)


def widest_segment(
    dense: NDArray, t: int, lo: int, hi: int, params: TrackingParams
) -> NDArray | None:
    """``dense`` without the markers measured through [lo, hi) that keep their distance
    to track ``t`` within ``rigid_fill_sd_mm`` SD but not to the largest group of such
    markers rigid to each other (see module); None when the most rigid one's group is
    the largest, the one the body's fills chose."""
    through = np.all(np.isfinite(dense[:, lo:hi]), axis=(1, 2))
    through[t] = False
    cand = np.flatnonzero(through)
    sd = distance_sd(dense[cand], dense[t][None])[:, 0]
    rigid = cand[np.argsort(sd)][: int(np.sum(sd <= params.rigid_fill_sd_mm))]
    if rigid.size < 3:
        return None
    mutual = distance_sd(dense[rigid], dense[rigid]) <= params.rigid_fill_sd_mm
    groups = []
    for first in range(rigid.size):  # a few markers: each one's group, greedily
        group = [first]
        for i in range(rigid.size):
            if i not in group and mutual[i, group].all():
                group.append(i)
        groups.append(group)
    widest = max(groups, key=len)
    if len(widest) <= len(groups[0]):
        return None
    out = dense.copy()
    out[np.delete(rigid, widest)] = np.nan
    return out


def unseen(chosen: Candidate, spare: SpareBlobs | None, params: TrackingParams) -> NDArray:
    """(n,) bool: the fields of ``chosen`` where no unused blob's ray meets it
    (:func:`~.rayfill.ray_correct`'s gate at its expected error)."""
    n = len(chosen.xyz_mm)
    if spare is None:
        return np.ones(n, dtype=bool)
    sd = chosen.fill.expected_error_mm
    return ray_correct(chosen.xyz_mm, chosen.fill.first_field, sd, spare, params)[1] == 0


def trusted_body(gap: Gap, a: int, b: int, params: TrackingParams) -> NDArray[np.bool_]:
    """Fill fields [a, b) of ``gap`` (a :class:`~kisscal.tracking.gap_record.Gap`) from the
    body (:data:`RIGID_METHODS`) through donors filled expecting at most
    ``max_body_fill_error_mm``, one of them over ``ray_rest_max_error_mm`` or only this
    pass's context (then by :data:`TURNING_METHODS`; see module): the candidate of least
    expected error, its donors' errors counted, at most ``max_body_fill_error_mm``
    (:func:`best_counted`), kept in the fields no unused blob's ray meets (:func:`unseen`),
    expecting at least its donors' noise and errors and those of the fills beside it, as
    the body's fills do. Returns the fields placed."""
    none = np.zeros(b - a, dtype=bool)
    if gap.errors is None or b - a > params.max_body_fill_fields:
        return none
    limit = params.max_body_fill_error_mm
    body = mirror_checked(gap.dense, gap.t, params, gap.mirror)
    body = trusted(body, gap.errors, gap.t, limit)
    bar = params.ray_rest_max_error_mm
    axis = tuple(m for m in RIGID_METHODS if m not in TURNING_METHODS)
    cands = over_bar(
        fill_candidates(body, gap.t, a, b, params, TURNING_METHODS), gap.errors, bar, gap.borrowed
    ) + over_bar(fill_candidates(body, gap.t, a, b, params, axis), gap.errors, bar)
    wide = widest_segment(body, gap.t, a, b, params)
    if wide is not None:  # donors the body's fills did not choose: no bar to pass
        cands += fill_candidates(wide, gap.t, a, b, params, RIGID_METHODS)
    chosen = best_counted(cands, gap.errors, params)
    if chosen is None:
        return none
    keep = unseen(chosen, gap.spare, params)
    got = [
        (chosen.xyz_mm[x:y], dataclasses.replace(chosen.fill, first_field=a + x, n_fields=y - x))
        for x, y in zip(*true_runs(keep), strict=True)
    ]
    got = donor_errors(donor_noise(got, gap.dense), gap.errors)
    got = anchored(got, gap.out, params.fill_context_fields)
    got = [g for g in got if g[1].expected_error_mm <= limit]
    gap.out.extend(got)
    return placed_mask(got, a, b)


#: The pass after :data:`~.fill_passes.LAST_PASS`, on what every fill left
#: (:func:`~.fill_runner.second_pass`): the body through trusted donors, then the thigh about
#: the hip and a knee no track took (:func:`~.fill_centre.trusted_centre_body`), then the
#: hip fill from the edges those placed (:func:`~.fill_hip.trusted_hip`).
TRUSTED_PASS = (
    Fill("trusted body", trusted_body),
    Fill("trusted body about a joint centre", trusted_centre_body),
    Fill("trusted hip", trusted_hip, rays=True, long_run=True),
)
