"""The segment's lengths: which tracks keep their distance to a marker over the trial
(its partners, :func:`length_partners`), how long that distance is across a gap
(:func:`partner_lengths`), and whether a partner was measured with the marker over
most of its motion (:func:`together`, :data:`MIN_TOGETHER`).

A marker seen by one camera lies on its blob's ray at the depth these lengths fix
(:mod:`kisscal.tracking.raychain` and the fills after it); the body's fills and the
labelling judge a marker's partners by them too.

References
----------
Challis 1995 (segments as rigid bodies of markers).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.bodyfill import distance_sd, ramp, side_windows
from kisscal.tracking.fill_donors import padded_mirrors
from kisscal.tracking.params import TrackingParams

#: Fewest fields a partner is measured in together with the marker, as a share of the
#: marker's measured fields: a thigh marker kept its distance to a shank one within
#: 2 mm over the 44 % of the trial both were seen (the knee straight), and drifted by
#: 10 mm in the swing the gap fell in.
MIN_TOGETHER = 0.5


def length_partners(
    dense: NDArray, t: int, params: TrackingParams, mirror: NDArray | None = None
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Tracks whose distance to track ``t`` keeps within ``rigid_fill_sd_mm`` SD over the
    trial (its segment's markers), measured together in at least ``body_context_fields``
    fields (a few fields may agree by chance), and that SD (at least
    ``ray_length_sd_floor_mm``). With ``mirror`` (each track's mirror image's track, -1
    for none), not one whose mirror pair's distance varies by more over the same fields:
    a pair across a knee held straight keeps its length while the other leg swings
    (kiss 3 seed 363, LTHI-LTIB 2.2 mm SD over LTIB's stance, RTHI-RTIB 19.9 mm there)."""
    seen = np.isfinite(dense[:, :, 0])
    if mirror is not None:
        mirror = padded_mirrors(mirror, len(dense))
    cand = np.flatnonzero((seen & seen[t]).sum(axis=1) >= params.length_fields)
    cand = cand[cand != t]
    sd = distance_sd(dense[cand], dense[t][None])[:, 0]
    keep = sd <= params.rigid_fill_sd_mm
    if mirror is not None and mirror[t] >= 0:
        m = mirror[cand]
        both = np.where(seen[cand] & seen[t], 1.0, np.nan)[..., None]
        pair = distance_sd(dense[np.maximum(m, 0)] * both, dense[mirror[t]][None])[:, 0]
        keep &= ~((m >= 0) & np.isfinite(pair) & (pair > params.rigid_fill_sd_mm))
    return cand[keep], np.maximum(sd[keep], params.ray_length_sd_floor_mm)


def partner_lengths(dense: NDArray, t: int, partners: NDArray, lo: int, hi: int, n: int) -> NDArray:
    """Length (mm) from track ``t`` to each partner per gap field (hi - lo, k): its mean
    in the ``n`` fields each side (the trial's where a side has none), drifting linearly
    across the gap."""
    dist = np.linalg.norm(dense[partners] - dense[t][None], axis=2)  # (k, n_fields)
    seen = np.isfinite(dist)
    dist = np.where(seen, dist, 0.0)

    def mean(f: NDArray | slice) -> NDArray:
        count = seen[:, f].sum(axis=1)
        return np.where(count > 0, dist[:, f].sum(axis=1) / np.maximum(count, 1), np.nan)

    before, after = (mean(f) for f in side_windows(dense[t], lo, hi, n))
    before = np.where(
        np.isfinite(before), before, np.where(np.isfinite(after), after, mean(slice(None)))
    )
    after = np.where(np.isfinite(after), after, before)
    w = ramp(lo, hi)[:, None]
    return before[None] * (1 - w) + after[None] * w


def together(dense: NDArray, t: int, partners: NDArray) -> NDArray[np.bool_]:
    """Whether each partner was measured with track ``t`` in at least
    :data:`MIN_TOGETHER` of ``t``'s fields: its length then held over most of the
    marker's motion, not only over a phase a joint held still in."""
    seen = np.isfinite(dense[t, :, 0])
    return (np.isfinite(dense[partners, :, 0]) & seen).sum(axis=1) >= MIN_TOGETHER * seen.sum()
