"""Single-camera fill from the blob itself: followed in the image, placed on its ray by
the segment's lengths.

Where a marker is seen by one camera only for longer than a spline bridges (a foot in
swing behind the other leg, in a lab of three or four cameras) and its segment has too
few markers in view for a rigid-body fill, the body's estimates are poor (a pattern fill
across the ankle misses by centimetres), so :mod:`kisscal.tracking.rayfill` has nothing
good to correct. The camera's blob is still there, unused by any 3D point: two of the
marker's three coordinates lie on its ray, and the third, the depth along the ray, is
fixed by the marker's distances to the other markers of its segment, constant in the
trial (the shank's knee, tibia and ankle markers; the foot's ankle, heel and toe;
:mod:`kisscal.tracking.segment_lengths`):

1. the blob is followed through the gap in each camera's image, from the marker's
   projection on each side of the gap (constant-velocity prediction, the nearest free
   blob within ``ray_chain_gate_px`` plus half a field's motion, none when a second is
   less than twice as far; blobs another track's image may share taken out first,
   :func:`~kisscal.tracking.fill_donors.unshared`); the two directions must agree where
   both found a blob (:func:`~kisscal.tracking.blob_paths.chain_blobs`);
2. on its ray, the depths where the distance to each partner equals its length (the
   ray meets the sphere) are refined by Gauss-Newton on all the partners' lengths at
   once (rays of two cameras: a point each, the one of smaller error kept where they
   agree); of these the one that continues the marker's path from both sides of the
   gap is taken (or the only one, on a blob followed in the image, unless a walk took
   it for the ray's other depth; or, where the path from one side joins no point of
   the gap, the one the other side's path takes without a break, when every partner
   was measured with the marker over most of its motion), where one reached it with its
   depth told (:func:`~.raywalk.told`); free blobs in fields no path reached are tried
   too, and kept only where both sides' paths agree;
3. the field is filled when every length agrees within three SDs and the expected error
   along the ray, ``1 / sqrt(sum cos² θ_u / σ_u²)`` (θ_u between the ray and the partner's
   direction, σ_u the SD of that length in the trial), is at most
   ``ray_length_max_error_mm``, in runs of at least :data:`~.on_rays.MIN_RUN` such fields;
   otherwise it is left to the other fills.

References
----------
Hartley & Zisserman 2004 (rays of a projective camera; least-squares point from rays);
Challis 1995 (segments as rigid bodies of markers); Gløersen & Federolf 2016 (filling
from the other markers of the body).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import ray_directions
from kisscal.tracking.blob_paths import chain_blobs
from kisscal.tracking.bodyfill import side_windows
from kisscal.tracking.fill_donors import unshared
from kisscal.tracking.on_rays import ChainFill, path_runs
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs, placed_errors
from kisscal.tracking.raywalk import agreed_pick, connected_picks, told, walk_picks
from kisscal.tracking.segment_lengths import length_partners, partner_lengths, together


def on_ray(
    centre: NDArray,
    d: NDArray,
    partners: NDArray,
    length: NDArray,
    sd: NDArray,
    iters: int = 8,
    placed_mm: NDArray | None = None,
) -> tuple[NDArray, NDArray, NDArray]:
    """Points of the ray ``centre + s d`` (unit ``d``) whose distances to ``partners``
    (m, 3) best match ``length`` (m,) weighed by ``1 / sd²``: from each place where the
    ray meets a partner's sphere (or passes nearest it), Gauss-Newton on all lengths.
    Returns the distinct points (p, 3), their largest length residual in SDs (p,) and
    their expected error along the ray (p,) mm: ``placed_mm`` (m,), each partner's own
    expected error (0 when measured), adds to its length's SD there (not in the fit nor
    the residual: a placed partner's error is the same over its run, and a looser SD
    would let a biased one through)."""
    rel = partners - centre
    b = rel @ d
    root = np.sqrt(np.maximum(length**2 - (np.sum(rel**2, axis=1) - b**2), 0.0))
    s = np.concatenate([b - root, b + root])
    for i in range(iters + 1):
        v = (centre + s[:, None] * d)[:, None] - partners[None]  # (S, m, 3)
        dist = np.linalg.norm(v, axis=2)
        res = (dist - length) / sd
        jac = (v @ d) / np.maximum(dist, 1e-9) / sd
        info = np.sum(jac**2, axis=1)
        if i < iters:
            step = np.sum(jac * res, axis=1) / np.maximum(info, 1e-12)
            s = s - np.clip(step, -100.0, 100.0)
    order = np.argsort(s)
    keep = order[np.r_[True, np.diff(s[order]) > 1.0]]
    if placed_mm is not None:
        info = np.sum((jac * sd / np.hypot(sd, placed_mm)) ** 2, axis=1)
    return (
        centre + s[keep, None] * d,
        np.abs(res[keep]).max(axis=1),
        1.0 / np.sqrt(np.maximum(info[keep], 1e-12)),
    )


def _apart(a: tuple, b: tuple) -> float:
    """Distance (mm) between two candidates' points."""
    return float(np.linalg.norm(a[0] - b[0]))


def _loose_rows(spare: SpareBlobs, lo: int, hi: int, ks: NDArray) -> tuple[NDArray, NDArray]:
    """Offsets and rows of every free blob in the gap's fields where no path in the
    image reached (the segment's lengths and the path in 3D judge them)."""
    rows = spare.rows(lo, hi)
    k = spare.field[rows] - lo
    keep = ~np.isin(k, ks)
    return k[keep], rows[keep]


def _candidates(
    dense: NDArray,
    partners: NDArray,
    sd: NDArray,
    length: NDArray,
    lo: int,
    ks: NDArray,
    rows: NDArray,
    spare: SpareBlobs,
    placed_mm: NDArray,
) -> dict[int, list]:
    """Per gap field offset, the points (xyz, expected error, row) on the rays of
    ``rows`` whose lengths to the partners seen there agree within three SDs; of points
    closer than 20 mm (two cameras' rays of the marker), the one of smallest error; none
    where two blobs' such points are farther apart than three combined expected errors.
    ``placed_mm`` (n_partners, n_fields): each partner's own expected error per field
    (:func:`on_ray`)."""
    cam = spare.camera[rows]
    d = ray_directions(spare.dlts[cam], spare.uv_px[rows])
    centres = spare.centres[cam]
    cands: dict[int, list] = {}
    for j, k in enumerate(ks.tolist()):
        seen = np.all(np.isfinite(dense[partners, lo + k]), axis=1)
        if not seen.any():
            continue
        where = dense[partners[seen], lo + k]
        own = placed_mm[seen, lo + k]
        got = on_ray(centres[j], d[j], where, length[k, seen], sd[seen], placed_mm=own)
        ok = got[1] <= 3.0
        for x, e in zip(got[0][ok], got[2][ok], strict=True):
            cands.setdefault(k, []).append((x, e, int(rows[j])))
    out: dict[int, list] = {}
    for k, v in cands.items():
        v.sort(key=lambda c: c[1])
        # two cameras' points of the marker that disagree: a merged blob's ray lies off
        # the marker's, and neither is sure
        if any(
            c[2] != o[2] and 3.0 * np.hypot(c[1], o[1]) < _apart(c, o) <= 20.0 for c in v for o in v
        ):
            continue
        out[k] = [c for i, c in enumerate(v) if all(_apart(c, o) > 20.0 for o in v[:i])]
    return out


def _walk_sides(target: NDArray, lo: int, hi: int, end: int) -> tuple[bool, bool]:
    """Whether the walk from before the run [lo, hi) of ``target`` and the one from
    after it start: a gap (``end`` 0) needs both sides' samples (and the field beyond
    each, for the path's velocity); a track's end (-1: before its first sample, 1:
    after its last) only the measured side's."""
    fwd = lo >= 2 and bool(np.all(np.isfinite(target[lo - 1])))
    bwd = hi + 1 < len(target) and bool(np.all(np.isfinite(target[hi])))
    if end == 0:
        return (True, True) if fwd and bwd else (False, False)
    return (fwd, False) if end > 0 else (False, bwd)


def _guide(dense: NDArray, partners: NDArray, lo: int, hi: int) -> NDArray[np.float64]:
    """The partner measured most in fields lo - 1 .. hi (NaN outside the trial), those
    fields of it, (hi - lo + 2, 3)."""
    f = np.arange(lo - 1, hi + 1)
    inside = (f >= 0) & (f < dense.shape[1])
    near = np.full((partners.size, f.size, 3), np.nan)
    near[:, inside] = dense[partners][:, f[inside]]
    return near[np.argmax(np.all(np.isfinite(near), axis=2).sum(axis=1))]


def unit_weight(
    dense: NDArray,
    t: int,
    partners: NDArray,
    sd: NDArray,
    ends: NDArray,
    centre: NDArray,
    lo: int,
    hi: int,
    params: TrackingParams,
) -> float:
    """How much more than :func:`on_ray` expects the lengths of ``partners`` (SDs
    ``sd``; ``ends`` (2, k): their lengths before and after the gap [lo, hi)) miss the
    depth of track ``t``'s own measured samples beside the gap, each on the ray from
    ``centre`` through it: the RMS of the misses over their expected errors, at least 1
    (1 without a sample to try). The trial's length SDs miss how noisy the partners
    are where few cameras see them (lowcost 306 RANK 39-60: 1.65 mm off expecting
    0.76); the sample's own noise counts in the miss, so it errs on the safe side."""
    before, after = side_windows(dense[t], lo, hi, params.body_context_fields)
    z = []
    for f, length in [(f, ends[0]) for f in before] + [(f, ends[1]) for f in after]:
        seen = np.all(np.isfinite(dense[partners, f]), axis=1) & np.isfinite(length)
        if not seen.any():
            continue
        d = (dense[t, f] - centre) / np.linalg.norm(dense[t, f] - centre)
        pts, _, e = on_ray(centre, d, dense[partners[seen], f], length[seen], sd[seen])
        miss = np.linalg.norm(pts - dense[t, f], axis=1)
        z.append(miss.min() / e[np.argmin(miss)])
    return float(max(1.0, np.sqrt(np.mean(np.square(z))))) if z else 1.0


def chain_fill(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    params: TrackingParams,
    end: int = 0,
    errors: NDArray | None = None,
    absent: NDArray | None = None,
    mirror: NDArray | None = None,
) -> ChainFill | None:
    """Place the gap [lo, hi) of track ``t`` of ``dense`` (n_tracks, n_fields, 3; NaN
    where not measured) on the rays of its own unused blobs (see module); None when no
    field could be placed. With ``end`` (-1: the fields before the track's first
    sample, 1: after its last), the run is a track's end, walked from its measured
    side only (a knee seen by one camera after its second camera lost it for good).
    With ``errors`` (n_tracks + m, n_fields: each sample's expected error, 0 where
    measured, NaN where unknown), a partner another fill placed counts its fill's error
    (:func:`~kisscal.tracking.rayfill.placed_errors`). ``absent`` (m, n_fields, 3): rows
    of names no track took, placed on one camera's rays
    (:func:`~kisscal.tracking.fill_absent.absent_placed`), partners too, numbered after
    the tracks (kiss 3 seed 323: a heel on one camera held by its toe and the placed
    ankle). ``mirror``: each row's mirror's row
    (:func:`~.segment_lengths.length_partners`; modern 3 seed 353's RTHI). The blobs
    taken are not marked used here."""
    if absent is not None and len(absent):
        dense = np.concatenate([dense, absent])
    target = dense[t]
    walk = _walk_sides(target, lo, hi, end)
    if not any(walk):
        return None
    partners, sd = length_partners(dense, t, params, mirror)
    held = together(dense, t, partners)
    steady = bool(held.all())
    # a length that held only over a phase a joint kept still in is no partner's (modern
    # 3 cameras seed 332: a thigh marker and the sacrum, 0.9 mm SD over the 24 % of the
    # thigh's fields both were seen, 14 mm over the trial: its ray placed 83 mm off)
    partners, sd = partners[held], sd[held]
    if partners.size == 0:
        return None
    spare = unshared(dense, t, lo, hi, spare, params, partners)
    ks, chained = chain_blobs(target, lo, hi, spare, params)
    k2, r2 = _loose_rows(spare, lo, hi, ks)
    length = partner_lengths(dense, t, partners, lo, hi, params.body_context_fields)
    ks, rows = np.r_[ks, k2], np.r_[chained, r2]
    own = placed_errors(dense, partners, errors, params)
    cands = _candidates(dense, partners, sd, length, lo, ks, rows, spare, own)
    if not cands:
        return None
    pts = {k: np.array([c[0] for c in v]) for k, v in cands.items()}
    order = sorted(pts)
    guide = _guide(dense, partners, lo, hi)
    coast = params.ray_chain_coast_fields
    fwd, no_f = walk_picks(pts, guide, target[lo - 1], -1, order, coast) if walk[0] else ({}, set())
    bwd, no_b = (
        walk_picks(pts, guide, target[hi], hi - lo, order[::-1], coast) if walk[1] else ({}, set())
    )
    near = (connected_picks(fwd, -1, coast), connected_picks(bwd, hi - lo, coast))
    if end or (fwd and bwd) or not steady:
        # one walk alone only where the other joins no point of the gap (its end is
        # not the marker's, or out of reach), and with lengths that held over the
        # marker's motion (a drifting one shows only as the two walks parting); at a
        # track's end no other walk can join: only a point alone on a followed blob
        near = (set(), set())
    xyz, err = np.full((hi - lo, 3), np.nan), np.full(hi - lo, np.nan)
    rows = np.full(hi - lo, -1)
    followed, clear = set(chained.tolist()), told(cands, params.ray_length_max_error_mm)
    for k, c in cands.items():
        i = agreed_pick(fwd.get(k), bwd.get(k), k in near[0], k in near[1]) if k in clear else None
        sure = len(c) == 1 and c[0][2] in followed and k not in no_f | no_b
        if i is not None or sure:
            x, e, row = c[0] if sure else c[i]
            if e <= params.ray_length_max_error_mm:
                xyz[k], err[k], rows[k] = x, e, row
    placed = path_runs(np.isfinite(err))
    xyz[~placed], err[~placed] = np.nan, np.nan
    taken = rows[placed]
    if not taken.size:
        return None
    cam = int(np.bincount(spare.camera[taken]).argmax())
    err *= unit_weight(dense, t, partners, sd, length[[0, -1]], spare.centres[cam], lo, hi, params)
    return ChainFill(xyz, err, tuple(int(p) for p in partners), np.asarray(taken, dtype=np.int64))
