"""Body fill about a marker and a joint centre: a thigh with one other marker.

A thigh carries two markers (thigh wand and knee). With the wand hidden and the knee
measured, the body fills find no pair of markers to carry it about
(:func:`~kisscal.tracking.bodyfill.axis_fill`, :mod:`kisscal.tracking.fill_hinge`), and
where one camera still sees it its ray cannot take the length fills' place: a camera in
front of or behind the walker looks along the normal of the plane of the wand, the knee
and the hip centre, so its ray meets both their spheres at a glancing angle (lowcost
seeds 413 RTHI, 401 LTHI, 420 LTHI: cosines under 0.11 to each over 12-15 fields, the
spline of its distance from the camera 2-8.5 mm off expecting 5-8). That direction is
the wand's turn about the thigh's axis, which the thigh holds from one side of the gap to
the other. So the joint centre the marker turns about (:mod:`.joint_centres`, the hip
carried by the pelvis) counts as a second carrier: the fills about a pair's axis are made
with it as one of the pair, their error measured on stretches of the marker's own samples
(:func:`~kisscal.tracking.stretches.expected_errors`), and moved onto the rays as the
body's fills are (:func:`~kisscal.tracking.fill_place.with_rays`): on lowcost 413 RTHI
1.28 mm RMS off (largest 2.13) expecting 1.36. Tried after the sphere fill: before it, it took
lowcost 416 LTHI, which the hip's sphere fixes well, from it (0.49 -> 1.06 mm RMS).

A knee seen by one camera only is often a marker no track took: its samples are rows
placed on its rays (:mod:`.fill_absent`), not a track, and the body's fills do not see
them, so the thigh has no partner to turn about the hip with (modern 3 seeds 409 RTHI
and 414 LTHI: one camera, then none, for 41-45 fields, left open). Last, in the trusted
pass (:func:`trusted_centre_body`), those rows are donors too, with every donor filled
expecting at most ``max_body_fill_error_mm``; each run where the knee and the centre are
known is filled on its own (a knee lost for a field or two bridged), its error measured
as a fill of the thigh's whole hole (the time it bridges) and at least its donors'
errors: on 409 RTHI 188-206, no camera seeing it, 1.19 mm RMS off (largest 2.21)
expecting 3.31, the knee's error along its ray; on 414 LTHI 171-213, its knee a track
filled since the first pass, 1.30 mm RMS off (largest 1.76) expecting 1.00.

References
----------
Gamage & Lasenby 2002 (functional joint centres); Challis 1995 (segments as rigid bodies
of markers); Gløersen & Federolf 2016 (gap filling from the other markers of the body).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import true_runs
from kisscal.tracking.bodyfill import (
    Candidate,
    axis_fill,
    best_candidate,
    fill_candidates,
)
from kisscal.tracking.fill_anchor import (
    anchored,
    body_donors,
    donor_errors,
    donor_noise,
    trusted,
)
from kisscal.tracking.fill_donors import bridged
from kisscal.tracking.fill_place import at_least, mirror_checked, placed_mask, with_rays
from kisscal.tracking.gap_record import Gap
from kisscal.tracking.joint_centres import Centres, joint_centres
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs
from kisscal.tracking.segment_lengths import length_partners
from kisscal.tracking.stretches import expected_errors
from kisscal.tracking.tracks import FILLED_RIGID

#: The fills about a pair's axis tried with a joint centre as one of the pair: the axis
#: fill alone. The hinge's cubic in the angle (:mod:`.fill_hinge`) expected 0.56 mm along
#: the ray on lowcost 413 RTHI's stretches and went 0.95 mm RMS off along it in the gap.
CENTRE_METHODS = ((FILLED_RIGID, axis_fill),)

#: Joint centres are sought among at most this many tracks: their rigid clusters
#: (:func:`~.joint_centres.rigid_clusters`) compare every pair of tracks over the trial, a
#: table of n² series (a real C3D file re-tracked from 1536 anonymous pieces asked for
#: 37 GB). A body's markers and their pieces are a few dozen tracks.
MAX_CENTRE_TRACKS = 100


def centre_candidate(
    body: NDArray,
    t: int,
    a: int,
    b: int,
    params: TrackingParams,
    joints: Centres,
    spare: SpareBlobs | None,
    hole: tuple[int, int] | None = None,
) -> Candidate | None:
    """The candidate of :data:`CENTRE_METHODS` for fields [a, b) of track ``t`` of
    ``body`` about a pair one of which is one of ``joints``' centres, of least expected
    error, at most ``max_body_fill_error_mm``, its centre's donors the cluster carrying
    it (``spare``: the blobs whose cameras' sight its error is measured along too). With
    ``hole`` (lo, hi), [a, b) a part of the track's hole where the pair is known, its
    error is measured as a fill of the whole hole (the time it bridges, the turn across
    it; the part's own edges are no samples of the track's)."""
    n = len(body)
    centres = spare.centres if spare is not None and spare.rows(a, b).size > 0 else None
    both = np.concatenate([body, joints.xyz_mm])
    cands = fill_candidates(both, t, a, b, params, CENTRE_METHODS, centres)
    # the pairs of markers alone were the body's (tried before this)
    cands = [c for c in cands if max(c.fill.donors) >= n]
    if hole is not None:
        cands = [_bridging(c, both, t, hole, params, centres) for c in cands]
    chosen = best_candidate(cands, params)
    if chosen is None:
        return None
    donors = sorted(
        {u for d in chosen.fill.donors for u in ((d,) if d < n else joints.clusters[d - n])}
    )
    return dataclasses.replace(chosen, fill=dataclasses.replace(chosen.fill, donors=tuple(donors)))


def _bridging(
    cand: Candidate,
    dense: NDArray,
    t: int,
    hole: tuple[int, int],
    params: TrackingParams,
    centres: NDArray | None,
) -> Candidate:
    """``cand`` (an axis fill of part of ``hole``) expecting the error of the axis fill
    bridging the whole ``hole`` of track ``t`` through its donors (on stretches of the
    track's own samples, :func:`~kisscal.tracking.stretches.expected_errors`)."""
    err, along = expected_errors(
        axis_fill, dense[t], dense, t, *hole, params, centres, cand.fill.donors
    )
    fill = dataclasses.replace(cand.fill, expected_error_mm=err)
    return dataclasses.replace(cand, fill=fill, along_sight_mm=along)


def centre_body(gap: Gap, a: int, b: int, params: TrackingParams) -> NDArray[np.bool_]:
    """Fill what :data:`CENTRE_METHODS` can of fields [a, b) of ``gap`` (a
    :class:`~kisscal.tracking.gap_record.Gap`) about a pair one of which is a joint centre
    (see module; :func:`centre_candidate`), moved onto the rays of blobs a camera still
    sees there, expecting at least its donors' noise and errors and those of the fills
    beside it, as the body's fills do."""
    none = np.zeros(b - a, dtype=bool)
    body = body_donors(gap, params)
    if len(body) > MAX_CENTRE_TRACKS:
        return none
    joints = joint_centres(body, gap.t, params, gap.mirror)
    if not joints.clusters:
        return none
    chosen = centre_candidate(body, gap.t, a, b, params, joints, gap.spare)
    return none if chosen is None else _placed(gap, chosen, a, b, params)


def _placed(
    gap: Gap,
    chosen: Candidate,
    a: int,
    b: int,
    params: TrackingParams,
    limit: float = np.inf,
    floor: float = np.nan,
) -> NDArray[np.bool_]:
    """``chosen`` moved onto the rays of ``gap``'s blobs, expecting at least its donors'
    noise and errors, those of the fills beside it and ``floor`` (mm; NaN: none),
    written into ``gap.out`` where it expects at most ``limit`` (mm) then; the fields of
    [a, b) placed."""
    spare = gap.spare
    rays = spare is not None and spare.rows(a, b).size > 0
    got = with_rays(chosen, spare, params) if rays else [(chosen.xyz_mm, chosen.fill)]
    got = donor_errors(donor_noise(got, gap.dense), gap.errors)
    got = anchored(got, gap.out, params.fill_context_fields)
    got = [(x, at_least(f, floor)) for x, f in got]
    got = [g for g in got if g[1].expected_error_mm <= limit]
    gap.out.extend(got)
    return placed_mask(got, a, b)


def trusted_centre_body(gap: Gap, a: int, b: int, params: TrackingParams) -> NDArray[np.bool_]:
    """Fill fields [a, b) of ``gap`` (a :class:`~kisscal.tracking.gap_record.Gap`) about a
    joint centre and a length partner, as :func:`centre_body`, through donors filled
    expecting at most ``max_body_fill_error_mm`` and the rows of markers no track took
    (``gap.absent``: a knee seen by one camera only, placed on its rays), each run
    where a partner and a centre are known filled on its own, the candidate expecting at
    least its donors' errors there, kept where that is at most ``max_body_fill_error_mm``
    (see module). Returns the fields placed."""
    none = np.zeros(b - a, dtype=bool)
    if gap.errors is None:
        return none
    full = gap.dense if gap.absent is None else np.concatenate([gap.dense, gap.absent])
    if len(full) > MAX_CENTRE_TRACKS:
        return none
    limit = params.max_body_fill_error_mm
    body = trusted(mirror_checked(full, gap.t, params, gap.mirror), gap.errors, gap.t, limit)
    joints = joint_centres(body, gap.t, params, gap.mirror)
    if not joints.clusters:
        return none
    partners = length_partners(body, gap.t, params, gap.mirror)[0]
    # a partner lost for a field or two is still there (its error: its neighbours')
    body = body.copy()  # not gap.dense's own rows: other tracks' fills read them
    lost = bridged(body, partners, np.arange(a, b), params.max_fill_gap_fields)
    body[partners, a:b] = lost.transpose(1, 0, 2)
    known = np.isfinite(body[partners, a:b, 0]).any(axis=0)
    known &= np.isfinite(joints.xyz_mm[:, a:b, 0]).any(axis=0)
    placed, n = none.copy(), len(gap.dense)
    for x, y in zip(*true_runs(known), strict=True):
        hole = (a, b) if x > 0 or y < b - a else None
        chosen = centre_candidate(body, gap.t, a + x, a + y, params, joints, gap.spare, hole)
        if chosen is None:
            continue
        # an untaken marker's row counts by its error, but is no track to name
        floor = donor_errors([(chosen.xyz_mm, chosen.fill)], gap.errors)[0][1].expected_error_mm
        donors = tuple(d for d in chosen.fill.donors if d < n)
        chosen = dataclasses.replace(chosen, fill=dataclasses.replace(chosen.fill, donors=donors))
        made = len(gap.out)
        placed |= _placed(gap, chosen, a, b, params, limit, floor)
        # written as the edges the trusted hip fill walks from (its fields' neighbours)
        placed_mask(gap.out[made:], a, b, gap.dense[gap.t])
    return placed
