"""Joint centres as length partners: the point of a neighbouring segment a marker turns
about, found on the trial itself.

A marker seen by one camera lies on its blob's ray; its depth along the ray is fixed by
its lengths to its segment's other markers (:mod:`kisscal.tracking.raychain`,
:mod:`kisscal.tracking.fill_sphere`). A thigh carries two markers (thigh wand and knee):
when the ray runs square to the line between them, it meets the knee's sphere at a
glancing angle and the depth is poorly fixed (modern 3 seed 304, RTHI seen by one camera
for 31 fields: the cosine of the ray to the knee fell from 0.11 to 0). The segment has a
third point that is not a marker: the joint it turns about on the next segment (the hip
joint centre, fixed in the pelvis). The thigh marker keeps its distance to it, and the
ray meets that sphere at another angle (0.16-0.26 there).

The centre is found functionally (Gamage & Lasenby 2002): for each rigid cluster of at
least three markers (pairwise distances within ``rigid_fill_sd_mm`` SD over the trial)
none of which keeps its distance to the marker, the samples of the marker and of its
segment's markers (its length partners) are expressed in the cluster's frame (Kabsch
1976 per field) and concentric spheres, one per marker, are fitted to them in closed
form (linear least squares in the centre and one constant per sphere). A centre is a
point of the marker's segment, so it is kept only when at least one partner is fitted
with the marker (seen over part of its motion alone, kiss 3 seed 303's RTIB, 106 fields,
fits a sphere in the pelvis's frame within 1.5 mm that its truth misses by 20 mm SD), each
radius keeps within ``rigid_fill_sd_mm`` SD over the trial, and the marker is seen in the
cluster's frame in :data:`~kisscal.tracking.segment_lengths.MIN_TOGETHER` of its fields (over
most of its motion, not a phase: modern 3 seed 307's LASI fitted one in the left shank's
frame, known in 59 fields, within 2.1 mm, its truth 23 mm SD off it). The point, carried
by the cluster into every field where its markers are known, is a partner of the
marker's. No names are used: a thigh marker about the pelvis's hip, a shank's about the
thigh's knee axis alike.

References
----------
Gamage & Lasenby 2002 (new least squares solutions for estimating the average centre of
rotation); Kabsch 1976 (best rotation between two point sets); Challis 1995 (segments as
rigid bodies of markers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.bodyfill import batch_kabsch, distance_sd
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.segment_lengths import MIN_TOGETHER, length_partners

#: Fewest markers of a cluster whose frame carries a centre (a pose needs three).
MIN_CLUSTER = 3


@dataclass(frozen=True)
class Centres:
    """Joint centres a marker keeps its distance to.

    Attributes
    ----------
    xyz_mm : (k, n_fields, 3) float array
        Each centre per field (NaN where its cluster is not all known).
    clusters : tuple of tuple of int
        The tracks whose frame carries each centre.
    """

    xyz_mm: NDArray[np.float64]
    clusters: tuple[tuple[int, ...], ...]


def sphere_centre(
    points: NDArray, member: NDArray | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Centre of the concentric spheres fitted to ``points`` (n, 3), one sphere per
    value of ``member`` (n,) int (default one), in closed form: ``|x|² = 2 x·c + k_m``
    is linear in the centre c and one constant per sphere (Gamage & Lasenby 2002's
    least squares, for one sphere; an arc spread in one direction only still gets the
    centre nearest its points). Returns the centre, and per sphere the mean distance of
    its points from it and their SD."""
    member = np.zeros(len(points), dtype=np.int64) if member is None else member
    m = int(member.max()) + 1
    shift = points.mean(axis=0)  # conditioning: |x|² of lab coordinates is large
    x = points - shift
    a = np.concatenate([2.0 * x, np.eye(m)[member]], axis=1)
    sol = np.linalg.lstsq(a, np.sum(x**2, axis=1), rcond=None)[0]
    dist = np.linalg.norm(x - sol[:3], axis=1)
    count = np.bincount(member, minlength=m)
    mean = np.bincount(member, dist, minlength=m) / count
    var = np.bincount(member, (dist - mean[member]) ** 2, minlength=m) / count
    return sol[:3] + shift, mean, np.sqrt(var)


def rigid_clusters(dense: NDArray, t: int, params: TrackingParams) -> list[NDArray[np.int64]]:
    """Clusters of at least :data:`MIN_CLUSTER` tracks of ``dense`` (n_tracks, n_fields,
    3) whose pairwise distances keep within ``rigid_fill_sd_mm`` SD over the trial,
    none of which keeps its distance to track ``t`` so (another segment than ``t``'s);
    grown greedily from each such track, each once."""
    sd = distance_sd(dense, dense)
    rigid = sd <= params.rigid_fill_sd_mm
    np.fill_diagonal(rigid, False)
    other = ~rigid[t] & np.isfinite(sd[t])
    other[t] = False
    out: list[NDArray[np.int64]] = []
    seen: set[tuple[int, ...]] = set()
    for u in np.flatnonzero(other).tolist():
        members = [u]
        for v in np.flatnonzero(rigid[u] & other).tolist():
            if rigid[v, members].all():
                members.append(v)
        key = tuple(sorted(members))
        if len(key) >= MIN_CLUSTER and key not in seen:
            seen.add(key)
            out.append(np.asarray(key, dtype=np.int64))
    return out


def _frames(dense: NDArray, cluster: NDArray) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Fields where every marker of ``cluster`` is known, and the cluster's pose there
    (rotations (m, 3, 3) and translations (m, 3)) from its shape in the first of them."""
    pts = dense[cluster]  # (k, n_fields, 3)
    known = np.flatnonzero(np.all(np.isfinite(pts), axis=(0, 2)))
    if known.size == 0:
        return known, np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros((0, 3))
    ref = pts[:, known[0]]
    r, tr = batch_kabsch(ref, np.transpose(pts[:, known], (1, 0, 2)))
    return known, r, tr, ref


def _local(dense: NDArray, members: NDArray, known: NDArray, r: NDArray, tr: NDArray) -> tuple:
    """Samples of ``members`` in the frames (``r``, ``tr``) of fields ``known``: points
    (n, 3) and the index into ``members`` of each (n,)."""
    own = dense[members][:, known]  # (m, k, 3)
    i, k = np.nonzero(np.isfinite(own[..., 0]))
    return np.einsum("nji,nj->ni", r[k], own[i, k] - tr[k]), i  # r.T (x - t)


def joint_centres(
    dense: NDArray, t: int, params: TrackingParams, mirror: NDArray | None = None
) -> Centres:
    """The joint centres track ``t`` of ``dense`` (n_tracks, n_fields, 3; NaN where not
    known) turns about (see module), one per cluster of :func:`rigid_clusters`; ``t`` and
    a partner (:func:`~kisscal.tracking.segment_lengths.length_partners`, ``mirror`` passed on)
    need ``body_context_fields`` samples in its frame."""
    n_fields = dense.shape[1]
    members = np.r_[t, length_partners(dense, t, params, mirror)[0]].astype(np.int64)
    fewest = params.length_fields
    mine = MIN_TOGETHER * np.isfinite(dense[t, :, 0]).sum()
    xyz, used = [], []
    for cluster in rigid_clusters(dense, t, params):
        known, r, tr, _ = _frames(dense, cluster)
        pts, who = _local(dense, members, known, r, tr)
        count = np.bincount(who, minlength=members.size)
        enough = count >= fewest
        if count[0] < mine or not enough[0] or enough.sum() < 2:
            continue
        keep = enough[who]
        kept = np.cumsum(enough) - 1  # members with enough samples, renumbered
        centre, _, sd = sphere_centre(pts[keep], kept[who[keep]])
        if not np.all(sd <= params.rigid_fill_sd_mm):
            continue
        at = np.full((n_fields, 3), np.nan)
        at[known] = np.einsum("nij,j->ni", r, centre) + tr
        xyz.append(at)
        used.append(tuple(int(c) for c in cluster))
    return Centres(
        np.asarray(xyz, dtype=float).reshape(len(xyz), n_fields, 3),
        tuple(used),
    )
