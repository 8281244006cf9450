"""Body fill of a gap through donors pulled out of shape in a few of its fields: made
across the whole gap, kept where its donors hold.

A donor whose blob merged with another marker's image is pulled off for a field or two
(lowcost 312: an ankle 10 mm off in one field of an 11-field tibia gap). The body fills
refuse donors out of shape anywhere in the gap (:func:`~.fill_donors.donors_hold`), and
with only two donors the fill is lost for the whole gap. Yet a rigid, two-marker or
hinge fill places each field from its donors in that field alone: a donor's bad field
spoils that field of the fill, not the others. So the samples out of shape are bridged
by a spline through the donor's own (so the methods run across the gap, from the same
side windows and with the same expected error, :func:`~.stretches.expected_errors`, as
without the pull), and the fields where the chosen fill's donors were bridged are
dropped from it.

References
----------
Challis 1995 (segments as rigid bodies of markers).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import true_runs
from kisscal.tracking.bodyfill import Candidate, best_candidate, fill_candidates
from kisscal.tracking.fill_anchor import anchored, body_donors, donor_errors, donor_noise
from kisscal.tracking.fill_donors import misfit_fields
from kisscal.tracking.fill_hinge import HINGE_METHODS
from kisscal.tracking.fill_place import placed_mask, with_rays
from kisscal.tracking.fill_spline import spline_fill
from kisscal.tracking.gap_record import Gap
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import FILLED_RIGID


def out_of_shape_fields(
    dense: NDArray, t: int, lo: int, hi: int, params: TrackingParams
) -> NDArray[np.bool_]:
    """(n_tracks, hi - lo): the gap fields where each track other than ``t`` misses two
    of its segment's mates or more (:func:`~.fill_donors.misfit_fields`; one marker
    pulled off misses all its mates, each of them misses it alone), or misses one that
    misses no more there (:func:`unpinned_fields`)."""
    return _flags(dense, t, lo, hi, params)[0]


def unpinned_fields(
    dense: NDArray, t: int, lo: int, hi: int, params: TrackingParams
) -> NDArray[np.bool_]:
    """(n_tracks, hi - lo): the gap fields where a track misses one mate of its segment
    that misses no more there and not two: the miss is pinned on neither (as
    :func:`~.fill_donors.unsound` says for a whole gap; lowcost 403, an ankle pulled 6 mm
    by a merged blob missed only the heel, its tibia hidden, the knee's length within
    its SDs), so both are flagged."""
    return _flags(dense, t, lo, hi, params)[1]


def _flags(
    dense: NDArray, t: int, lo: int, hi: int, params: TrackingParams
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """:func:`out_of_shape_fields` and, of them, :func:`unpinned_fields`."""
    miss = np.zeros((len(dense), len(dense), hi - lo), dtype=bool)
    seen = np.flatnonzero(np.isfinite(dense[:, lo:hi, 0]).any(axis=1))
    for k in seen[seen != t].tolist():
        # one track at a time: a fill's donors count as mates of each other
        miss[k] = misfit_fields(dense, t, (k,), lo, hi, params)[0]
    count = miss.sum(axis=1)
    unpinned = (count == 1) & np.any(miss & (count[None] <= count[:, None, :]), axis=1)
    return (count >= 2) | unpinned, unpinned


def _bridged(dense: NDArray, flagged: NDArray, lo: int, params: TrackingParams) -> NDArray:
    """A copy of ``dense`` whose samples ``flagged`` (n_tracks, m) from field ``lo`` are
    replaced by the spline through each track's samples beside them (NaN without)."""
    src = dense.copy()
    for k in np.flatnonzero(flagged.any(axis=1)).tolist():
        src[k, lo : lo + flagged.shape[1]][flagged[k]] = np.nan
        series = src[k].copy()
        for a, b in zip(*true_runs(flagged[k]), strict=True):
            got = spline_fill(series, src, k, lo + a, lo + b, params)
            if got is not None:
                src[k, lo + a : lo + b] = got[0]
    return src


def held_body(gap: Gap, a: int, b: int, params: TrackingParams) -> NDArray[np.bool_]:
    """Fill what the body (with the hinge, :data:`~.fill_hinge.HINGE_METHODS`) can of
    fields [a, b) of ``gap`` (a :class:`~kisscal.tracking.gap_record.Gap`) where some track
    is out of shape in some of them (see module): the fill of least expected error, at
    most ``max_body_fill_error_mm``, made with those samples bridged, kept in the
    fields where none of its donors was; each piece moved onto the rays of blobs a
    camera still sees there (:func:`~.fill_place.with_rays`; where a donor's miss is
    pinned on neither, :func:`unpinned_fields`, only those), expecting at least its
    donors' noise and the error of the fills beside it as the body's fills do, and, when
    a rigid fill expecting at most ``ray_rest_max_error_mm``, written into ``gap.dense``
    as context (the fields dropped lie between its pieces). Returns the fields placed."""
    flagged, unpinned = _flags(gap.dense, gap.t, a, b, params)
    rays = gap.spare is not None and gap.spare.rows(a, b).size > 0
    centres = gap.spare.centres if rays else None
    seen = np.isfinite(gap.dense[:, a:b, 0])
    absent = ~seen & seen.any(axis=1, keepdims=True)
    absent[gap.t] = False
    chosen = None
    # then, where no fill is made so, the tracks absent in part of the run bridged too,
    # and kept on rays alone as a miss pinned on neither (lowcost 406: a tibia on one
    # camera whose knee was placed only in half of the run, 12 fields 0.6 mm RMS off)
    for more in (np.zeros_like(absent), absent & rays):
        if chosen is None and (flagged | more).any():
            src = _bridged(body_donors(gap, params), flagged | more, a, params)
            cands = fill_candidates(src, gap.t, a, b, params, HINGE_METHODS, centres)
            chosen = best_candidate(cands, params)
            flagged, unpinned = flagged | more, unpinned | more
    if chosen is None:
        return np.zeros(b - a, dtype=bool)
    donors = list(chosen.fill.donors)
    keep = ~flagged[donors].any(axis=0)
    # a donor's miss pinned on neither: the fill is kept only where a camera's ray
    # measures it (lowcost 311: a toe hinged about heel and ankle, the two missing each
    # other in one field, 8 fields no camera saw 4.1 mm RMS off expecting 2.9)
    rayed_only = bool(unpinned[donors].any())
    context = (
        chosen.fill.status == FILLED_RIGID
        and chosen.fill.expected_error_mm <= params.ray_rest_max_error_mm
    )
    out: list = []
    for x, y in zip(*true_runs(keep), strict=True):
        fill = dataclasses.replace(chosen.fill, first_field=a + x, n_fields=y - x)
        piece = Candidate(chosen.xyz_mm[x:y], fill, chosen.along_sight_mm)
        got = with_rays(piece, gap.spare, params) if rays else [(piece.xyz_mm, fill)]
        got = donor_errors([g for g in got if g[1].ray_fields or not rayed_only], gap.errors)
        # as the body's fills (:func:`~.fill_body.spline_or_body`; lowcost 403 LTIB beside a chain
        # fill expecting 3.4 mm, 1.1 mm RMS off expecting 0.6 on its ray)
        out += anchored(donor_noise(got, gap.dense), gap.out, params.fill_context_fields)
    gap.out.extend(out)
    for xyz, f in out if context else ():
        gap.dense[gap.t, f.first_field : f.first_field + f.n_fields] = xyz
    return placed_mask(out, a, b)
