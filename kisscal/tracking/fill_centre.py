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
(:func:`~kisscal.tracking.bodyfill.expected_errors`), and moved onto the rays as the
body's fills are (:func:`~kisscal.tracking.fill_place.with_rays`): on lowcost 413 RTHI
1.28 mm RMS off (largest 2.13) expecting 1.36. Tried after the sphere fill: before it, it took
lowcost 416 LTHI, which the hip's sphere fixes well, from it (0.49 -> 1.06 mm RMS).

References
----------
Gamage & Lasenby 2002 (functional joint centres); Challis 1995 (segments as rigid bodies
of markers); Gløersen & Federolf 2016 (gap filling from the other markers of the body).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.bodyfill import axis_fill, best_candidate, fill_candidates
from kisscal.tracking.fill_anchor import anchored, body_donors, donor_errors, donor_noise
from kisscal.tracking.fill_place import placed_mask, with_rays
from kisscal.tracking.gap_record import Gap
from kisscal.tracking.joint_centres import joint_centres
from kisscal.tracking.params import TrackingParams
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


def centre_body(gap: Gap, a: int, b: int, params: TrackingParams) -> NDArray[np.bool_]:
    """Fill what :data:`CENTRE_METHODS` can of fields [a, b) of ``gap`` (a
    :class:`~kisscal.tracking.gap_record.Gap`) about a pair one of which is a joint centre
    (see module): the candidate of least expected error, at most
    ``max_body_fill_error_mm``, its centre's donors the cluster carrying it, moved onto
    the rays of blobs a camera still sees there, expecting at least its donors' noise and
    errors and those of the fills beside it, as the body's fills do; none among more
    than :data:`MAX_CENTRE_TRACKS` tracks."""
    none = np.zeros(b - a, dtype=bool)
    body = body_donors(gap, params)
    if len(body) > MAX_CENTRE_TRACKS:
        return none
    joints = joint_centres(body, gap.t, params, gap.mirror)
    if not joints.clusters:
        return none
    n = len(body)
    spare = gap.spare
    rays = spare is not None and spare.rows(a, b).size > 0
    centres = spare.centres if rays else None
    cands = fill_candidates(
        np.concatenate([body, joints.xyz_mm]), gap.t, a, b, params, CENTRE_METHODS, centres
    )
    # the pairs of markers alone were the body's (tried before this)
    chosen = best_candidate([c for c in cands if max(c.fill.donors) >= n], params)
    if chosen is None:
        return none
    donors = sorted(
        {u for d in chosen.fill.donors for u in ((d,) if d < n else joints.clusters[d - n])}
    )
    chosen = dataclasses.replace(
        chosen, fill=dataclasses.replace(chosen.fill, donors=tuple(donors))
    )
    got = with_rays(chosen, spare, params) if rays else [(chosen.xyz_mm, chosen.fill)]
    got = donor_errors(donor_noise(got, gap.dense), gap.errors)
    gap.out.extend(anchored(got, gap.out, params.fill_context_fields))
    return placed_mask(got, a, b)
