"""Whether the markers a body fill follows through a gap are measured sound there.

A body fill's expected error (:func:`~kisscal.tracking.bodyfill.expected_errors`) is
measured beside the gap, where its donors are sound. A donor measured wrong in the gap
carries the fill with it, and nothing beside the gap shows it: in a lab of three or four
cameras the hidden marker's image is often hidden *in* a donor's (their blobs merged), and
the donor's 3D point is pulled towards it (lowcost 303: an ankle 14 mm off where the heel
was hidden; the heel, filled about the ankle-toe axis, 13 mm off expecting 1.6). Such a
donor shows as a distance to the markers of its segment that does not hold in the gap.

References
----------
Challis 1995 (segments as rigid bodies of markers); Gløersen & Federolf 2016 (gap
filling from the other markers of the body).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.params import TrackingParams

#: Largest misfit of a donor's distance to a marker of its segment in a gap field, in SDs
#: of that distance over the trial (at least ``ray_length_sd_floor_mm``): beyond it the
#: donor is not measured sound there. Four: a gap of 100 fields and a few such distances
#: makes hundreds of draws, which three SDs of noise alone would fail one in two of.
DONOR_MISFIT_SD = 4.0


def donors_hold(
    dense: NDArray,
    t: int,
    donors: tuple[int, ...],
    lo: int,
    hi: int,
    params: TrackingParams,
) -> bool:
    """Whether the ``donors`` of a fill of the gap [lo, hi) of track ``t`` keep, in every
    field of the gap, their distances to each other and to the other markers of their
    segment (SD over the trial at most ``rigid_fill_sd_mm``), within
    :data:`DONOR_MISFIT_SD` SDs of the trial's mean; fields where either is not measured
    are not judged.

    Parameters
    ----------
    dense : (n_tracks, n_fields, 3) array
        Measured positions of every track (NaN elsewhere).
    t : int
        The filled track (not judged: hidden in the gap).
    donors : tuple of int
        Tracks the fill follows.
    lo, hi : int
        The gap (fields lo..hi-1).
    params : TrackingParams

    Returns
    -------
    bool
        False when a donor is out of shape in some field of the gap.
    """
    if not donors:
        return True
    k = np.asarray(donors, dtype=np.int64)
    dist = np.linalg.norm(dense[k][:, None] - dense[None], axis=3)  # (k, n_tracks, n_fields)
    seen = np.isfinite(dist)
    n = seen.sum(axis=2)
    mean = np.where(seen, dist, 0.0).sum(axis=2) / np.maximum(n, 1)
    var = np.where(seen, (dist - mean[..., None]) ** 2, 0.0).sum(axis=2) / np.maximum(n, 1)
    sd = np.where(n >= 4, np.sqrt(var), np.inf)
    mates = (sd <= params.rigid_fill_sd_mm) | np.isin(np.arange(len(dense)), k)[None]
    mates[:, t] = False
    mates[np.arange(k.size), k] = False
    miss = (
        np.abs(dist[:, :, lo:hi] - mean[..., None])
        / np.maximum(sd, params.ray_length_sd_floor_mm)[..., None]
    )
    out = mates[..., None] & np.isfinite(miss) & (miss > DONOR_MISFIT_SD)
    return not bool(np.any(out))


def axis_frames(origin: NDArray, toward: NDArray, ref: NDArray) -> NDArray[np.float64]:
    """Rotations (n, 3, 3) whose first column points from ``origin`` to ``toward`` (n, 3)
    and whose third is square to it and to the lab direction ``ref`` (a frame of two
    markers; its turn about their axis follows the lab)."""
    u = toward - origin
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(u, ref)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    return np.stack([u, np.cross(w, u), w], axis=2)


def _local(target: NDArray, dense: NDArray, donors: tuple[int, ...], f: NDArray) -> NDArray:
    """``target`` at fields ``f`` in its donors' frame: its offset from a lone donor; with
    two, its place along their axis and its offset from it in the frame of
    :func:`axis_frames` (turning about the axis with the lab);
    NaN with more (their frame turns with them)."""
    rel = target[f] - dense[donors[0], f]
    if len(donors) == 1:
        return rel
    if len(donors) > 2:
        return np.full_like(rel, np.nan)
    axis = dense[donors[1], f] - dense[donors[0], f]
    ref = np.eye(3)[int(np.argmin(np.abs(np.nanmean(axis, axis=0))))]
    r = axis_frames(dense[donors[0], f], dense[donors[1], f], ref)
    return np.einsum("nji,nj->ni", r, rel)


def moved(target: NDArray, dense: NDArray, donors: tuple[int, ...], spans: NDArray) -> NDArray:
    """How far (mm) ``target`` moved in its donors' frame (:func:`_local`) between the
    fields just outside each span (lo, hi) of ``spans`` (m, 2): 0 where one is outside
    the trial or not measured."""
    ends = np.c_[spans[:, 0] - 1, spans[:, 1]]
    inside = (ends >= 0) & (ends < len(target))
    local = _local(target, dense, donors, np.where(inside, ends, 0).ravel()).reshape(-1, 2, 3)
    d = np.linalg.norm(local[:, 1] - local[:, 0], axis=1)
    return np.where(inside.all(axis=1) & np.isfinite(d), d, 0.0)


def phase_matched(
    stretches: list[tuple[int, int]],
    target: NDArray,
    dense: NDArray,
    donors: tuple[int, ...],
    gap: tuple[int, int],
    floor: float,
) -> list[tuple[tuple[int, int], float]]:
    """``stretches`` (pseudo-gaps, nearest first,
    :func:`~kisscal.tracking.bodyfill.pseudo_gaps`) in the order to measure a fill of
    ``gap`` (lo, hi) following one or two ``donors`` on (the first two the fill can be
    made on), each with the factor its error is scaled up by.

    One or two donors do not fix their segment's turn about them (a heel about its
    ankle, or about the ankle-toe axis, as the foot rolls at heel strike); the fills
    carry the target across the gap from its place on each side (linearly, or by a cubic
    in the angle) and miss a share of a turn between the two, which stretches cut where
    the foot is flat do not show. So the stretches are taken in the same phase of the
    motion: those where the target moved in its donors' frame (:func:`moved`) most
    nearly as far as across the gap (by ratio; the nearer first among equals), their
    error scaled by ``(d_gap + floor) / (d_stretch + floor)`` where it moved less (a
    share of the turn; moves under ``floor`` mm are noise). With three donors or more
    (their frame turns with them), the two nearest, unscaled."""
    if not 1 <= len(donors) <= 2 or not stretches:
        return [(s, 1.0) for s in stretches[:2]]
    ratio = (moved(target, dense, donors, np.array([gap, *stretches])) + floor) / floor
    ratio = ratio[0] / ratio[1:]
    best = np.argsort(np.abs(np.log(ratio)), kind="stable")
    return [(stretches[i], max(1.0, float(ratio[i]))) for i in best.tolist()]
