"""Measured samples that break their segment's lengths are not the marker's.

With two cameras a marker's 3D point can be wrong for a run of fields and still be the
only point near its path: its blob merged with a neighbour's in one camera (the
detector's centroid lies between the two), so the point is tens of mm off and drifts
back as the blobs part. The tracker takes it, and the wrong samples then spoil every
length check that uses them (an unnamed piece of a segment partner fails its join, a
gap beside them is filled towards them). A named trajectory's measured sample is dropped
(left to gap filling) when its distances to at least two of the trajectory's rigid
partners measured in that field, and to most of them, differ from their usual lengths
by far more than noise: more than :data:`BREAK_SDS` robust SDs of that length and than
twice ``label_segment_tolerance_mm``. One partner alone cannot tell which of the two is
wrong; two that agree with each other and not with the sample can.

Rigid partners are the tracks measured together with it in at least
``body_context_fields`` fields whose distance to it keeps an SD of at most
``rigid_fill_sd_mm``, the SD taken robustly as the :data:`SPREAD_QUANTILE` quantile of
the distance's deviation from its median over that of a normal deviation: a tenth of
the fields may be wrong without hiding the partner that exposes them, while a marker
across a joint (a thigh's to a shank's, the knee straight half the stride) is no
partner.

References
----------
Shafiq et al. 2001 (rigid segment lengths as a check on a tracked marker's identity).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.result import Labelling
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import MEASURED, make_tracks, numbering

#: A length broken by more than this many robust SDs (and twice the label tolerance).
BREAK_SDS = 8.0

#: Quantile of a length's absolute deviation from its median taken as its spread, and
#: that quantile of a normal deviation's absolute value (in SDs).
SPREAD_QUANTILE = 0.9
NORMAL_QUANTILE_SDS = 1.645


def broken_fields(dense: NDArray, t: int, params: TrackingParams) -> NDArray[np.bool_]:
    """Fields (n_fields,) where track ``t``'s measured sample breaks its rigid lengths
    (see module); ``dense`` is (n_tracks, n_fields, 3), NaN where not measured."""
    dist = np.linalg.norm(dense - dense[t][None], axis=2)  # (n_tracks, n_fields)
    seen = np.isfinite(dist)
    seen[t] = False
    enough = seen.sum(axis=1) >= params.length_fields
    if not enough.any():
        return np.zeros(dense.shape[1], dtype=bool)
    dist, seen = dist[enough], seen[enough]
    with np.errstate(invalid="ignore"):
        length = np.nanmedian(dist, axis=1)
        spread = np.nanquantile(np.abs(dist - length[:, None]), SPREAD_QUANTILE, axis=1)
    sd = spread / NORMAL_QUANTILE_SDS
    rigid = sd <= params.rigid_fill_sd_mm
    dist, seen, length, sd = dist[rigid], seen[rigid], length[rigid], sd[rigid]
    limit = np.maximum(BREAK_SDS * sd, 2.0 * params.label_segment_tolerance_mm)
    off = seen & (np.abs(np.where(seen, dist, 0.0) - length[:, None]) > limit[:, None])
    n_off, n_seen = off.sum(axis=0), seen.sum(axis=0)
    return (n_off >= 2) & (2 * n_off > n_seen)


def drop_broken_samples(labelling: Labelling, params: TrackingParams) -> Labelling:
    """``labelling`` without the named trajectories' measured samples that break their
    segment's lengths (see module); track numbers and names kept."""
    tr = labelling.tracks
    if tr.field.size == 0 or not labelling.fits_marker_set:
        return labelling
    meas = tr.status == MEASURED
    dense = np.full((tr.n_tracks, int(tr.field.max()) + 1, 3), np.nan)
    dense[tr.track[meas], tr.field[meas]] = tr.xyz_mm[meas]
    unnamed = set(labelling.unlabelled)
    bad = np.zeros(dense.shape[:2], dtype=bool)
    for t in range(tr.n_tracks):
        if t not in unnamed:
            bad[t] = broken_fields(dense, t, params)
    drop = meas & bad[tr.track, tr.field]
    # a track keeps at least one sample, so that numbering and names stay as they were
    left = np.bincount(tr.track[~drop], minlength=tr.n_tracks)
    drop &= left[tr.track] > 0
    if not drop.any():
        return labelling
    keep = ~drop
    cols = [getattr(tr, c)[keep] for c in ("field", "track", "xyz_mm", "corrected_mm")]
    ids, rank, _ = numbering(cols[0], cols[1])
    old = np.empty(ids.size, dtype=np.int64)
    old[rank] = ids
    out = make_tracks(*cols, tr.status[keep], tr.point[keep])
    labels = tuple(labelling.labels[o] for o in old.tolist())
    unlabelled = tuple(i for i, o in enumerate(old.tolist()) if o in unnamed)
    return dataclasses.replace(labelling, tracks=out, labels=labels, unlabelled=unlabelled)
