"""Single-camera fill from the blob itself: followed in the image, placed on its ray by
the segment's lengths.

Where a marker is seen by one camera only for longer than a spline bridges (a foot in
swing behind the other leg, in a lab of three or four cameras) and its segment has too
few markers in view for a rigid-body fill, the body's estimates are poor (a pattern fill
across the ankle misses by centimetres), so :mod:`kisscal.tracking.rayfill` has nothing
good to correct. The camera's blob is still there, unused by any 3D point: two of the
marker's three coordinates lie on its ray, and the third, the depth along the ray, is
fixed by the marker's distances to the other markers of its segment, constant in the
trial (the shank's knee, tibia and ankle markers; the foot's ankle, heel and toe):

1. the blob is followed through the gap in each camera's image, from the marker's
   projection on each side of the gap (constant-velocity prediction, the nearest free
   blob within ``ray_chain_gate_px`` plus half a field's motion, none when a second is
   less than twice as far; blobs another track's image may share taken out first,
   :func:`~kisscal.tracking.fill_donors.unshared`); the two directions must agree where
   both found a blob;
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
   ``ray_length_max_error_mm``, in runs of at least :data:`MIN_RUN` such fields;
   otherwise it is left to the other fills.

References
----------
Hartley & Zisserman 2004 (rays of a projective camera; least-squares point from rays);
Challis 1995 (segments as rigid bodies of markers); Gløersen & Federolf 2016 (filling
from the other markers of the body).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import true_runs
from kisscal.dlt.model import project_rows, ray_directions
from kisscal.tracking.bodyfill import distance_sd, ramp, side_windows
from kisscal.tracking.fill_donors import padded_mirrors, unshared
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs, placed_errors
from kisscal.tracking.raywalk import agreed_pick, connected_picks, told, walk_picks

#: Fewest consecutive fields placed on rays for them to be kept.
MIN_RUN = 2

#: Fewest fields a partner is measured in together with the marker, as a share of the
#: marker's measured fields: a thigh marker kept its distance to a shank one within
#: 2 mm over the 44 % of the trial both were seen (the knee straight), and drifted by
#: 10 mm in the swing the gap fell in.
MIN_TOGETHER = 0.5


def path_runs(placed: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The fields of ``placed`` in runs of at least :data:`MIN_RUN`: a path, not a
    stray field."""
    out = np.zeros(placed.shape, dtype=bool)
    for a, b in zip(*true_runs(placed), strict=True):
        out[a:b] = b - a >= MIN_RUN
    return out


@dataclass(frozen=True)
class ChainFill:
    """A gap's fields placed on the rays of the marker's own blobs.

    Attributes
    ----------
    xyz_mm : (n, 3) float array
        Position per gap field (NaN where none was placed).
    sd_mm : (n,) float array
        Expected error per field (NaN where none was placed).
    partners : tuple of int
        Tracks whose distances fixed the depth.
    rows : int array
        Rows of the spare blobs taken.
    """

    xyz_mm: NDArray[np.float64]
    sd_mm: NDArray[np.float64]
    partners: tuple[int, ...]
    rows: NDArray[np.int64]


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


def follow_blobs(
    spare: SpareBlobs, cam: int, uv: NDArray, vel: NDArray, fields: NDArray, params: TrackingParams
) -> dict[int, int]:
    """The blob rows of camera ``cam`` that continue a path in the image from ``uv`` with
    velocity ``vel`` (px/field) over ``fields`` (consecutive, either direction); the
    path coasts over at most ``ray_chain_coast_fields`` fields without a blob."""
    found: dict[int, int] = {}
    missed = 0
    for f in fields.tolist():
        pred = uv + vel
        a, b = np.searchsorted(spare.field, [f, f + 1])
        rows = np.arange(a, b)
        rows = rows[spare.free[rows] & (spare.camera[rows] == cam)]
        dist = np.sort(np.linalg.norm(spare.uv_px[rows] - pred, axis=1))
        gate = params.ray_chain_gate_px + 0.5 * float(np.linalg.norm(vel))
        if dist.size and dist[0] <= gate and (dist.size == 1 or dist[1] >= 2.0 * dist[0]):
            row = int(rows[np.argmin(np.linalg.norm(spare.uv_px[rows] - pred, axis=1))])
            found[f] = row
            vel, uv, missed = spare.uv_px[row] - uv, spare.uv_px[row], 0
            continue
        uv, missed = pred, missed + 1
        if missed > params.ray_chain_coast_fields:
            break
    return found


def side_paths(
    target: NDArray, lo: int, hi: int, spare: SpareBlobs, params: TrackingParams
) -> list[tuple[dict[int, int], dict[int, int]]]:
    """Per camera, the marker's blobs (field: spare row) in the gap [lo, hi) of
    ``target`` (n_fields, 3) followed in the image from the side before the gap and from
    the side after it (:func:`follow_blobs`, from the marker's projection there)."""
    out = []
    for cam in range(len(spare.dlts)):
        picks = []
        for edge, step, fields in (
            (lo - 1, -1, np.arange(lo, hi)),
            (hi, 1, np.arange(hi - 1, lo - 1, -1)),
        ):
            if not 0 <= edge < len(target):  # a run at the trial's start or end: one side
                picks.append({})
                continue
            ends = target[[edge, edge + step if 0 <= edge + step < len(target) else edge]]
            if not np.all(np.isfinite(ends[0])):
                picks.append({})
                continue
            ends = np.where(np.isfinite(ends), ends, ends[:1])
            uv = project_rows(spare.dlts, [cam, cam], ends)
            picks.append(follow_blobs(spare, cam, uv[0], uv[0] - uv[1], fields, params))
        out.append((picks[0], picks[1]))
    return out


def chain_blobs(
    target: NDArray, lo: int, hi: int, spare: SpareBlobs, params: TrackingParams
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Gap field offsets and spare rows of the marker's blobs in the gap [lo, hi) of
    ``target`` (n_fields, 3), followed in every camera from both sides (see module)."""
    ks, rows = [], []
    for fwd, bwd in side_paths(target, lo, hi, spare, params):
        for f in sorted(set(fwd) | set(bwd)):
            if f in fwd and f in bwd and fwd[f] != bwd[f]:
                continue
            ks.append(f - lo)
            rows.append(fwd.get(f, bwd.get(f)))
    return np.asarray(ks, dtype=np.int64), np.asarray(rows, dtype=np.int64)


def parted(target: NDArray, lo: int, hi: int, spare: SpareBlobs, params: TrackingParams) -> bool:
    """Whether the marker's blobs followed in a camera's image from the two sides of the
    run [lo, hi) of ``target`` (n_fields, 3) part in some field (:func:`side_paths`):
    the two sides' samples are then not ends of one path in the image, and one of them
    may be another marker's (a sample of two merged images)."""
    return any(
        f in bwd and bwd[f] != row
        for fwd, bwd in side_paths(target, lo, hi, spare, params)
        for f, row in fwd.items()
    )


def one_camera_blobs(
    ks: NDArray[np.int64], rows: NDArray[np.int64], spare: SpareBlobs
) -> tuple[int, NDArray[np.int64], NDArray[np.int64]]:
    """The camera that sees most of a gap's blobs (``ks``, ``rows`` as
    :func:`chain_blobs`), and its blobs, the first of each field."""
    cam = int(np.bincount(spare.camera[rows]).argmax())
    keep = spare.camera[rows] == cam
    ks, first = np.unique(ks[keep], return_index=True)
    return cam, ks, rows[keep][first]


def off_rays(
    at: NDArray, ks: NDArray, o_ks: NDArray, o_rows: NDArray, spare: SpareBlobs, gate: float
) -> NDArray[np.int64]:
    """Gap offsets of ``ks`` (ascending) whose point ``at`` (m, 3) lies farther than
    ``gate`` mm from the ray of a blob of the marker there (offsets ``o_ks``, rows
    ``o_rows``; the point's own blob is on its ray): a second camera's blob disagrees,
    and one of the two is not the marker's alone (a merged blob's centroid lies off
    both markers' rays)."""
    if ks.size == 0:
        return np.zeros(0, dtype=np.int64)
    i = np.searchsorted(ks, o_ks)
    hit = (i < ks.size) & (ks[np.minimum(i, ks.size - 1)] == o_ks)
    i, o_rows = i[hit], o_rows[hit]
    return np.unique(ks[i[ray_miss_mm(spare, o_rows, at[i]) > gate]])


def ray_miss_mm(spare: SpareBlobs, rows: NDArray, xyz: NDArray) -> NDArray[np.float64]:
    """Distance (mm) of each lab point ``xyz`` (m, 3) from the ray of its blob ``rows``."""
    cam = spare.camera[rows]
    d = ray_directions(spare.dlts[cam], spare.uv_px[rows])
    rel = xyz - spare.centres[cam]
    return np.linalg.norm(rel - np.einsum("ij,ij->i", rel, d)[:, None] * d, axis=1)


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


def together(dense: NDArray, t: int, partners: NDArray) -> NDArray[np.bool_]:
    """Whether each partner was measured with track ``t`` in at least
    :data:`MIN_TOGETHER` of ``t``'s fields: its length then held over most of the
    marker's motion, not only over a phase a joint held still in."""
    seen = np.isfinite(dense[t, :, 0])
    return (np.isfinite(dense[partners, :, 0]) & seen).sum(axis=1) >= MIN_TOGETHER * seen.sum()


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
    ankle). ``mirror``: each row's mirror's row (:func:`length_partners`; modern 3 seed
    353's RTHI). The blobs taken are not marked used here."""
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
