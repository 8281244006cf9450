"""Single-camera fill with the depth from the body, smoothed across the gap.

Where one camera alone sees a marker, it lies on the ray of its blob (followed in the
image, :func:`~kisscal.tracking.blob_paths.chain_blobs`) and only its depth along the ray is
unknown. Each partner of its segment measured in that field (a marker whose distance to
it keeps within ``rigid_fill_sd_mm`` over the trial) puts it on a sphere about the
partner, which the ray meets at two depths. :mod:`kisscal.tracking.raychain` takes such a
point field by field when the lengths alone fix it well; with one partner seen at a
glancing angle (the ray nearly tangent to the sphere) or only now and then, they do not,
and a spline alone (:mod:`kisscal.tracking.fill_depth`) drifts over a long gap. Here both
count, in one fit of the depth over the fields of the gap:

* the depth ``s`` per field is a random walk on its acceleration (SD: the RMS second
  difference of the marker's measured distance from that camera over the trial), with
  the distances of the measured samples on each side of the gap as data (SD
  ``ray_length_sd_floor_mm``): alone, it is the cubic bridging the gap;
* each partner's root, where the ray meets the sphere, is a datum of SD
  ``sd_L / cos θ`` (``sd_L`` the length's SD in the trial, θ between the ray and the
  direction to the partner); a ray within ``acos(MIN_COS)`` of tangent (where the two
  roots merge and a small error moves the depth a lot) gives none; the joint centres
  the marker turns about (:mod:`kisscal.tracking.joint_centres`: a thigh marker's hip,
  carried by the pelvis) are partners too, where the ray runs square to the segment's
  own markers (modern 3 seed 304's RTHI, cos to the knee 0.11 -> 0, to the hip 0.16-0.26);
* of the two roots, the one nearest the current fit is taken when the other lies outside
  three SDs of it; starting from the spline, the fit is redone as roots near the gap's
  ends tighten it, until the choice settles; a root more than three SDs from the final
  fit is dropped and the fit redone;
* a Kalman filter of the same walk walks the gap from each side, taking roots against
  its prediction alike (each root taken tightens the next prediction): where either
  takes a root the fit did not, one of them followed the wrong branch of the spheres,
  and the gap is left to the other fills;
* a partner another fill placed (the passes after the first) adds its own error to its
  roots' SD in the depth's SD (not in their choice): ``ray_rest_max_error_mm``, the
  most such a partner may expect, or, where the roots taken come from two partners or
  more, which check each other, what its fill expects, if less (one placed partner
  alone: nothing checks its fill's claim).

A field is placed where the posterior SD of its depth (the fit's covariance) is at most
``ray_depth_max_error_mm``, in runs of at least
:data:`~kisscal.tracking.on_rays.MIN_RUN` fields; that SD is its expected error.

References
----------
Hartley & Zisserman 2004 (rays of a projective camera); Challis 1995 (segments as rigid
bodies of markers); Rauch, Tung & Striebel 1965 (fixed-interval smoothing of a random
walk); Gløersen & Federolf 2016 (gap filling from what the trial measured).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import project_rows, ray_directions
from kisscal.tracking.blob_paths import chain_blobs, off_rays, one_camera_blobs
from kisscal.tracking.bodyfill import side_windows
from kisscal.tracking.joint_centres import joint_centres
from kisscal.tracking.on_rays import ChainFill, path_runs
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs
from kisscal.tracking.segment_lengths import MIN_TOGETHER, length_partners, partner_lengths

#: Smallest cosine between a ray and the direction from its root to the partner for the
#: partner's length to fix a depth (nearer tangent, the two roots merge).
MIN_COS = 0.1

#: Most refits while roots far from the fit are dropped.
MAX_ROUNDS = 30


def sphere_roots(
    centre: NDArray, d: NDArray, partners: NDArray, length: NDArray, sd: NDArray
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Depths where rays ``centre + s d`` (n, 3 each; unit ``d``) meet the spheres of
    radius ``length`` (n,) about ``partners`` (n, 3): (n, 2), nearer first, and their SD
    ``sd / cos θ`` (n,); NaN where the ray misses or is within :data:`MIN_COS` of
    tangent."""
    rel = partners - centre
    b = np.einsum("ij,ij->i", rel, d)
    disc = length**2 - (np.sum(rel**2, axis=1) - b**2)
    half = np.sqrt(np.maximum(disc, 0.0))
    cos = half / np.maximum(length, 1e-9)
    ok = (disc > 0) & (cos >= MIN_COS)
    roots = np.where(ok[:, None], b[:, None] + np.c_[-half, half], np.nan)
    return roots, np.where(ok, sd / np.maximum(cos, 1e-9), np.nan)


def smooth_depth(
    n: int, idx: NDArray, value: NDArray, sd: NDArray, acc_sd: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Posterior mean and SD of depths ``s`` (n,) under a random walk on their second
    difference (SD ``acc_sd``) given data ``value`` (SD ``sd``) at indices ``idx``
    (repeats allowed); the data must fix a line (two distinct indices at least)."""
    d2 = np.diff(np.eye(n), 2, axis=0)
    a = d2.T @ d2 / acc_sd**2
    w = 1.0 / sd**2
    np.add.at(a, (idx, idx), w)
    rhs = np.zeros(n)
    np.add.at(rhs, idx, w * value)
    cov = np.linalg.inv(a)
    return cov @ rhs, np.sqrt(np.maximum(np.diag(cov), 0.0))


def _pick(roots: NDArray, rsd: NDArray, mean: NDArray, msd: NDArray) -> NDArray[np.float64]:
    """Per datum, the root of ``roots`` (m, 2) nearest the fit ``mean`` (m,) when the
    other lies outside three combined SDs of it and it within; NaN otherwise."""
    gate = 3.0 * np.sqrt(msd**2 + rsd**2)
    dist = np.abs(roots - mean[:, None])
    near = np.argmin(dist, axis=1)
    rows = np.arange(len(roots))
    first, other = dist[rows, near], dist[rows, 1 - near]
    ok = (first <= gate) & ~(other <= gate)
    return np.where(ok, roots[rows, near], np.nan)


def _walk(n: int, ends: tuple, data: tuple, acc_sd: float, forward: bool) -> NDArray:
    """The root taken per datum (NaN where none) by a Kalman filter of the depth (a
    random walk on its second difference, SD ``acc_sd``) walking the ``n`` fields from
    one side: from that side's ``ends`` (index, depth, SD; the gap's data lie between
    the two sides' ends), each datum (index, roots (m, 2), SD) taken by :func:`_pick`
    against the filter's prediction and then used by it."""
    e_idx, e_val, e_sd = ends
    idx, roots, rsd = data
    side = e_idx < idx.min() if forward else e_idx > idx.max()
    e_idx, e_val, e_sd = e_idx[side], e_val[side], e_sd[side]
    taken = np.full(idx.size, np.nan)
    f = np.array([[2.0, -1.0], [1.0, 0.0]])
    x, p = np.full(2, e_val[0]), np.diag([e_sd[0] ** 2, 1e6])
    started = False
    for i in range(n) if forward else range(n - 1, -1, -1):
        if started:
            x, p = f @ x, f @ p @ f.T + np.diag([acc_sd**2, 0.0])
        z = [(v, sd) for v, sd in zip(e_val[e_idx == i], e_sd[e_idx == i], strict=True)]
        j = np.flatnonzero(idx == i)
        if j.size and started:
            spread = np.full(j.size, np.sqrt(p[0, 0]))
            taken[j] = _pick(roots[j], rsd[j], np.full(j.size, x[0]), spread)
            z += [(taken[k], rsd[k]) for k in j if np.isfinite(taken[k])]
        for v, sd in z:
            gain = p[:, 0] / (p[0, 0] + sd**2)
            x, p = x + gain * (v - x[0]), p - np.outer(gain, p[0])
            started = True
    return taken


def _bridge(
    n: int, ends: tuple[NDArray, NDArray, NDArray], data: tuple, acc_sd: float
) -> tuple[NDArray, NDArray, NDArray]:
    """:func:`smooth_depth` on the ``ends`` (index, depth, SD) and the roots of ``data``
    (index, roots (m, 2), SD) taken by :func:`_pick` against it, refitted until the
    choice settles and no root taken lies more than three SDs from the fit. Returns the
    mean, its SD and the depth taken per datum (NaN where none)."""
    e_idx, e_val, e_sd = ends
    idx, roots, rsd = data
    mean, msd = smooth_depth(n, e_idx, e_val, e_sd, acc_sd)
    taken = np.full(len(idx), np.nan)
    # a root off the spline by more than three SDs of both (it tells nearest the ends):
    # the length does not hold in the gap (a partner across a joint)
    far = np.abs(roots - mean[idx, None]) > 3.0 * np.sqrt(msd[idx, None] ** 2 + rsd[:, None] ** 2)
    dropped = np.all(far, axis=1)
    for _ in range(MAX_ROUNDS):
        new = np.where(dropped, np.nan, _pick(roots, rsd, mean[idx], msd[idx]))
        if np.array_equal(new, taken, equal_nan=True):
            bad = np.abs(taken - mean[idx]) > 3.0 * rsd
            if not bad.any():
                break
            dropped |= bad
            new[bad] = np.nan
        taken = new
        use = np.isfinite(taken)
        mean, msd = smooth_depth(
            n, np.r_[e_idx, idx[use]], np.r_[e_val, taken[use]], np.r_[e_sd, rsd[use]], acc_sd
        )
    return mean, msd, taken


def _fit(
    n: int, ends: tuple[NDArray, NDArray, NDArray], data: tuple, acc_sd: float
) -> tuple[NDArray, NDArray, NDArray] | None:
    """:func:`_bridge`, checked by walks from each side (:func:`_walk`): None when a
    walk takes a root the bridge does not (one of them followed the wrong branch of the
    spheres)."""
    mean, msd, taken = _bridge(n, ends, data, acc_sd)
    if not np.isfinite(taken).any():
        return None
    for side in (True, False):
        walk = _walk(n, ends, data, acc_sd, side)
        if np.any(np.isfinite(walk) & ~(walk == taken)):
            return None
    return mean, msd, taken


def acceleration_sd(own: NDArray, centre: NDArray) -> float:
    """RMS second difference (mm/field²) of the distance of ``own`` (n_fields, 3; NaN
    where not measured) from ``centre``, over its runs of three measured fields; NaN
    without one."""
    dd = np.diff(np.linalg.norm(own - centre, axis=1), 2)
    dd = dd[np.isfinite(dd)]
    return float(np.sqrt(np.mean(dd**2))) if dd.size else float("nan")


def _gap_data(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    rows: NDArray,
    ks: NDArray,
    params: TrackingParams,
    mine: NDArray,
    known: NDArray | None = None,
    expected: NDArray | None = None,
    mirror: NDArray | None = None,
) -> tuple[NDArray, NDArray, list[tuple[int, ...]], tuple[NDArray, NDArray, NDArray], NDArray]:
    """Rays (centres, directions) of ``rows`` (one per gap offset of ``ks``), and every
    partner's sphere roots on the rays: the tracks of each datum's partner (m,; a joint
    centre's are its cluster's, :mod:`.joint_centres`), (datum offset, roots (m, 2),
    SD (m,)) and a factor on each SD (:func:`_placed_factor`, with ``expected``; ones
    without ``known``).
    ``mine`` (n_fields,) bool: the marker's own samples (for :data:`MIN_TOGETHER`);
    ``mirror``: each track's mirror image's (:func:`~.segment_lengths.length_partners`)."""
    cam = spare.camera[rows]
    d = ray_directions(spare.dlts[cam], spare.uv_px[rows])
    c = spare.centres[cam]
    d *= np.sign(np.einsum("ij,ij->i", dense[t, lo - 1] - c, d))[:, None]  # towards it
    # the joints the marker turns about are partners too (past the tracks' rows): the
    # thigh's hip where the ray runs square to the thigh's two markers
    joints = joint_centres(dense, t, params, mirror)
    tracks = [(int(u),) for u in range(len(dense))] + list(joints.clusters)
    if mirror is not None:  # a centre has no mirror track
        mirror = np.r_[
            np.where(mirror < len(dense), mirror, -1)[: len(dense)], [-1] * len(joints.clusters)
        ]
    dense = np.concatenate([dense, joints.xyz_mm])
    partners, psd = length_partners(dense, t, params, mirror)
    # rigid over most of the marker's motion, not over a phase a joint held still in
    together = (np.isfinite(dense[partners, :, 0]) & mine).sum(axis=1)
    keep = together >= MIN_TOGETHER * mine.sum()
    partners, psd = partners[keep], psd[keep]
    length = partner_lengths(dense, t, partners, lo, hi, params.body_context_fields)
    j, p = np.meshgrid(np.arange(ks.size), np.arange(partners.size), indexing="ij")
    j, p = j.ravel(), p.ravel()
    where = dense[partners[p], lo + ks[j]]
    seen = np.all(np.isfinite(where), axis=1)
    j, p, where = j[seen], p[seen], where[seen]
    roots, rsd = sphere_roots(c[j], d[j], where, length[ks[j], p], psd[p])
    factor = np.ones((2, rsd.size))
    if known is not None:
        args = (known, tracks, partners[p], lo + ks[j], psd[p], params)
        factor = np.stack([_placed_factor(*args), _placed_factor(*args, expected)])
    ok = np.isfinite(rsd)
    data = (ks[j[ok]], roots[ok], rsd[ok])
    return c, d, [tracks[u] for u in partners[p[ok]]], data, factor[:, ok]


def _placed_factor(
    known: NDArray,
    tracks: list,
    partners: NDArray,
    f: NDArray,
    sd: NDArray,
    params: TrackingParams,
    expected: NDArray | None = None,
) -> NDArray[np.float64]:
    """Factor on the SD of each root (partner rows ``partners`` of ``tracks``: a track,
    or a joint centre's cluster; at fields ``f``; length SD ``sd``) for a partner there
    that ``known`` ((n_tracks, n_fields) bool: measured samples) does not hold (a centre:
    one of its cluster's): placed by another fill, its own error adds to the length's
    (kiss 3 seed 306, RTIB on a placed ankle 2-3 mm off: 5.6 mm off expecting 1.3):
    ``ray_rest_max_error_mm``, the most a placed partner may expect, or with
    ``expected`` ((n_tracks, n_fields), each track's expected error there, NaN where
    not known) what the fill that placed it expects, if less (a centre: its cluster's
    largest)."""
    rows = [known] + [known[list(c)].all(axis=0)[None] for c in tracks[len(known) :]]
    placed = ~np.concatenate(rows)[partners, f]
    err = np.full(f.size, params.ray_rest_max_error_mm)
    if expected is not None:
        own = [expected] + [expected[list(c)].max(axis=0)[None] for c in tracks[len(known) :]]
        err = np.fmin(np.concatenate(own)[partners, f], err)
    return np.where(placed, np.hypot(sd, err) / sd, 1.0)


def _crowded(
    dense: NDArray, t: int, lo: int, ks: NDArray, rows: NDArray, spare: SpareBlobs, px: float
) -> NDArray[np.bool_]:
    """Which blobs (``rows``, at gap offsets ``ks``) lie within ``px`` of where another
    track known in that field projects: the blob may be that marker's, or the two
    markers' merged into one at their centroid, off the target's ray."""
    others = np.delete(dense[:, lo + ks], t, axis=0)  # (n_tracks - 1, m, 3)
    known = np.isfinite(others[..., 0])
    j = np.nonzero(known)
    uv = project_rows(spare.dlts, spare.camera[rows][j[1]], others[j])
    near = np.linalg.norm(uv - spare.uv_px[rows][j[1]], axis=1) <= px
    out = np.zeros(ks.size, dtype=bool)
    out[j[1][near]] = True
    return out


def alone_blobs(
    dense: NDArray, t: int, lo: int, hi: int, spare: SpareBlobs, params: TrackingParams
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Gap offsets and rows of the blobs of track ``t`` followed in the image through the
    gap [lo, hi) (:func:`~kisscal.tracking.blob_paths.chain_blobs`) that lie farther than
    twice ``ray_chain_gate_px`` from every other track known there (:func:`_crowded`)."""
    ks, rows = chain_blobs(dense[t], lo, hi, spare, params)
    if ks.size == 0:
        return ks, rows
    alone = ~_crowded(dense, t, lo, ks, rows, spare, 2.0 * params.ray_chain_gate_px)
    return ks[alone], rows[alone]


def _contradicted(
    series: NDArray, own: NDArray, centre: NDArray, f0: int, mean: NDArray, msd: NDArray, err: float
) -> bool:
    """Whether the fitted depth ``mean`` (SD ``msd``; fields from ``f0``) misses the
    distance from ``centre`` of a sample of ``series`` placed by another fill (in
    ``series``, not in ``own``; expected error at most ``err``) by more than three
    combined SDs: the fit followed another marker's blob or the wrong branch of the
    spheres (lowcost seed 311, with a looser one-sided rule in the chain fill: RANK fitted
    on the blobs of the heel hiding it, 10-18 mm off, beside fields placed 2-4 mm off on
    its own blobs in another camera)."""
    f = f0 + np.arange(mean.size)
    f = f[f < len(series)]
    placed = np.isfinite(series[f, 0]) & ~np.isfinite(own[f, 0])
    f = f[placed]
    miss = np.abs(np.linalg.norm(series[f] - centre, axis=1) - mean[f - f0])
    return bool(np.any(miss > 3.0 * np.hypot(msd[f - f0], err)))


def sphere_depth_fill(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    params: TrackingParams,
    measured: NDArray | None = None,
    known: NDArray | None = None,
    expected: NDArray | None = None,
    mirror: NDArray | None = None,
    blobs: tuple[NDArray, NDArray] | None = None,
) -> ChainFill | None:
    """Place fields of the gap [lo, hi) of track ``t`` of ``dense`` (n_tracks, n_fields,
    3; NaN where not measured) on the rays of its own blobs in the camera that sees most
    of the gap, at the depth fitted to the spline across the gap and its segment's
    lengths (see module); None when no run of
    :data:`~kisscal.tracking.on_rays.MIN_RUN` fields is placed or no length was used.
    With ``measured`` ((n_fields,) bool), the ends of the fit are only those samples of
    the track. With ``known`` ((n_tracks, n_fields) bool, the measured samples), a
    partner placed by another fill counts its error too (:func:`_placed_factor`):
    ``ray_rest_max_error_mm``, or, where the roots taken come from two partners or more
    (each checks the other), what ``expected`` ((n_tracks, n_fields), each track's
    expected error, NaN where not known) says its fill expects there, if less.
    ``mirror``: each track's mirror image's track, -1 for none (the partners' test,
    :func:`~kisscal.tracking.segment_lengths.length_partners`). The
    blobs taken are not marked used here. ``blobs``: the gap offsets and rows of the
    marker's blobs, when the caller chose them (:mod:`.fill_unmerged`); by default
    those followed in the image that no other track's image is near."""
    series = dense[t]
    if lo < 2 or hi + 1 >= len(series) or not np.all(np.isfinite(series[[lo - 1, hi]])):
        return None
    ks, rows = alone_blobs(dense, t, lo, hi, spare, params) if blobs is None else blobs
    if ks.size == 0:
        return None
    # every blob followed as the marker's checks the point, another track's image near
    # it or not (lowcost 311 RANK 22-28: camera 1's blob the heel's, taken, 14.6 mm off
    # expecting 1.7; camera 2's the ankle's own, beside the toe's image)
    every = (ks, rows) if blobs is not None else chain_blobs(series, lo, hi, spare, params)
    cam, ks, rows = one_camera_blobs(ks, rows, spare)
    own = series if measured is None else np.where(measured[:, None], series, np.nan)
    centre = spare.centres[cam]
    acc = acceleration_sd(own, centre)
    before, after = side_windows(own, lo, hi, params.fill_context_fields)
    if before.size < 2 or after.size < 2 or not acc > 0:
        return None
    f0 = int(before[0])
    n = int(after[-1]) + 1 - f0
    ends_f = np.r_[before, after]
    ends = (
        ends_f - f0,
        np.linalg.norm(own[ends_f] - centre, axis=1),
        np.full(ends_f.size, params.ray_length_sd_floor_mm),
    )
    c, d, partners, (k_data, roots, rsd), factor = _gap_data(
        dense, t, lo, hi, spare, rows, ks, params, np.isfinite(own[:, 0]), known, expected, mirror
    )
    fit = _fit(n, ends, (k_data + lo - f0, roots, rsd), acc)
    if fit is None:
        return None
    mean, msd, taken = fit
    if _contradicted(series, own, centre, f0, mean, msd, params.ray_length_max_error_mm):
        return None
    # the roots are chosen and checked as measured partners' are (a placed partner's
    # error is the same over its run: looser SDs let a biased one through); the SD of
    # the depth counts it: the bound, or what its fill expects where another partner's
    # roots check it (resting on one, kiss 3 seed 306's RTIB on an ankle placed 1.8 mm
    # RMS off expecting 1.3 went 4.3 mm off expecting 2.3)
    use = np.isfinite(taken)
    checked = len({partners[k] for k in np.flatnonzero(use)}) >= 2
    e_idx, e_val, e_sd = ends
    msd = smooth_depth(
        n,
        np.r_[e_idx, k_data[use] + lo - f0],
        np.r_[e_val, taken[use]],
        np.r_[e_sd, (rsd * factor[int(checked)])[use]],
        acc,
    )[1]
    s, sd = mean[ks + lo - f0], msd[ks + lo - f0]
    at = c + s[:, None] * d
    good = np.zeros(hi - lo, dtype=bool)
    good[ks] = sd <= params.ray_depth_max_error_mm
    good[off_rays(at, ks, *every, spare, params.ray_depth_max_error_mm)] = False
    placed = path_runs(good)
    take = placed[ks]
    if not take.any():
        return None
    xyz, err = np.full((hi - lo, 3), np.nan), np.full(hi - lo, np.nan)
    xyz[ks[take]] = at[take]
    err[ks[take]] = sd[take]
    used = {u for k in np.flatnonzero(np.isfinite(taken)) for u in partners[k]}
    return ChainFill(xyz, err, tuple(sorted(used)), rows[take])
