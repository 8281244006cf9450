"""Whether the markers a fill follows through a gap are measured sound there, and which
blobs a single-camera fill may take as the marker's own (:func:`shared_blobs`).

A body fill's expected error (:func:`~kisscal.tracking.stretches.expected_errors`) is
measured beside the gap, where its donors are sound. A donor measured wrong in the gap
carries the fill with it, and nothing beside the gap shows it: in a lab of three or four
cameras the hidden marker's image is often hidden *in* a donor's (their blobs merged), and
the donor's 3D point is pulled towards it (lowcost 303: an ankle 14 mm off where the heel
was hidden; the heel, filled about the ankle-toe axis, 13 mm off expecting 1.6). Such a
donor shows as a distance to the markers of its segment that does not hold in the gap;
with three donors or more, the one to blame is left out (:func:`sound_fill`).

References
----------
Challis 1995 (segments as rigid bodies of markers); Gløersen & Federolf 2016 (gap
filling from the other markers of the body); Hartley & Zisserman 2004 (projection).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import project_rows
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs

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
    return not bool(np.any(unsound(dense, t, donors, lo, hi, params)))


def unsound(
    dense: NDArray, t: int, donors: tuple[int, ...], lo: int, hi: int, params: TrackingParams
) -> NDArray[np.bool_]:
    """Per donor, whether it is not measured sound in the gap [lo, hi) (see
    :func:`donors_hold`): it misses two mates or more (:func:`out_of_shape`), or misses
    one that misses fewer itself (the miss cannot be pinned on either). A miss with a
    mate out of shape is the mate's (lowcost 312: a knee, carrying a tibia hidden where
    the ankle's point was pulled 5 mm by a merged blob, missed the ankle alone)."""
    bad = misfits(dense, t, donors, lo, hi, params)
    far = np.flatnonzero(bad.any(axis=0))
    pinned = np.zeros(len(dense), dtype=bool)
    pinned[far] = misfits(dense, t, tuple(far.tolist()), lo, hi, params).sum(axis=1) >= 2
    return (bad.sum(axis=1) >= 2) | np.any(bad & ~pinned[None], axis=1)


def misfits(
    dense: NDArray, t: int, donors: tuple[int, ...], lo: int, hi: int, params: TrackingParams
) -> NDArray[np.bool_]:
    """(len(donors), n_tracks): which distances from each donor to a mate of its segment
    miss the trial's mean by more than :data:`DONOR_MISFIT_SD` SDs in some field of the
    gap [lo, hi) (see :func:`donors_hold`)."""
    return misfit_fields(dense, t, donors, lo, hi, params).any(axis=2)


def misfit_fields(
    dense: NDArray, t: int, donors: tuple[int, ...], lo: int, hi: int, params: TrackingParams
) -> NDArray[np.bool_]:
    """:func:`misfits` field by field: (len(donors), n_tracks, hi - lo).

    Only tracks measured somewhere in the gap can miss there, so distances are taken to
    those alone, one coordinate at a time (a whole trial of every donor against every
    track made this the tracking stage's largest cost in a long trial).
    """
    k = np.asarray(donors, dtype=np.int64)
    out = np.zeros((k.size, len(dense), hi - lo), dtype=bool)
    cols = np.flatnonzero(np.isfinite(dense[:, lo:hi]).all(axis=2).any(axis=1))
    if not k.size or not cols.size:
        return out
    dist, mean, sd = distance_stats(dense[k], dense[cols])
    mates = (sd <= params.rigid_fill_sd_mm) | np.isin(cols, k)[None]
    mates &= (cols != t)[None] & (cols[None] != k[:, None])
    with np.errstate(invalid="ignore"):
        miss = (
            np.abs(dist[:, :, lo:hi] - mean[..., None])
            / np.maximum(sd, params.ray_length_sd_floor_mm)[..., None]
        )
    out[:, cols] = mates[..., None] & (miss > DONOR_MISFIT_SD)
    return out


def distance_stats(a: NDArray, b: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """Distances (k, m, n) between each series of ``a`` (k, n, 3) and each of ``b``
    (m, n, 3), and their mean and SD (k, m) over the fields where both are measured (SD
    inf with fewer than 4 such fields).

    Summed a coordinate at a time: no (k, m, n, 3) temporary; over a long trial, with
    every candidate fill asking, these were most of a re-track's time."""
    sq = np.zeros((len(a), len(b), a.shape[1]))
    for c in range(3):
        sq += (a[:, None, :, c] - b[None, :, :, c]) ** 2
    dist = np.sqrt(sq)
    seen = np.isfinite(dist)
    count = seen.sum(axis=2)
    n = np.maximum(count, 1)
    mean = np.where(seen, dist, 0.0).sum(axis=2) / n
    dev = np.where(seen, dist - mean[..., None], 0.0)
    sd = np.sqrt((dev * dev).sum(axis=2) / n)
    return dist, mean, np.where(count >= 4, sd, np.inf)


def out_of_shape(
    dense: NDArray, t: int, donors: tuple[int, ...], lo: int, hi: int, params: TrackingParams
) -> NDArray[np.int64]:
    """The ``donors`` that miss two mates or more in the gap [lo, hi) (:func:`misfits`):
    one marker pulled off, as by a hidden marker's image merged into its own, misses all
    its mates, and each of those misses it alone."""
    bad = misfits(dense, t, donors, lo, hi, params)
    return np.asarray(donors, dtype=np.int64)[bad.sum(axis=1) >= 2]


def sound_fill(
    method: Callable, dense: NDArray, t: int, lo: int, hi: int, params: TrackingParams
) -> tuple[tuple[NDArray, tuple[int, ...]] | None, NDArray]:
    """A body fill ``method``'s (positions, donors) for the gap [lo, hi) of track ``t``
    through donors that hold in the gap (:func:`donors_hold`), and the positions it was
    made from: ``dense``, or, where three donors or more do not hold and the misfit is
    one's (:func:`out_of_shape`), a copy without that donor (the method made again from
    the rest; its error is to be measured without it too). (None, dense) when none."""
    got = method(dense[t], dense, t, lo, hi, params)
    if got is None or donors_hold(dense, t, got[1], lo, hi, params):
        return got, dense
    bad = out_of_shape(dense, t, got[1], lo, hi, params) if len(got[1]) >= 3 else []
    if not len(bad):
        return None, dense
    src = dense.copy()
    src[bad] = np.nan
    got = method(dense[t], src, t, lo, hi, params)
    if got is None or not donors_hold(dense, t, got[1], lo, hi, params):
        return None, dense
    return got, src


def axis_frames(origin: NDArray, toward: NDArray, ref: NDArray) -> NDArray[np.float64]:
    """Rotations (n, 3, 3) whose first column points from ``origin`` to ``toward`` (n, 3)
    and whose third is square to it and to the lab direction ``ref`` (a frame of two
    markers; its turn about their axis follows the lab)."""
    u = toward - origin
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(u, ref)
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    return np.stack([u, np.cross(w, u), w], axis=2)


def lab_reference(axis: NDArray) -> NDArray[np.float64]:
    """The lab axis (3,) that ``axis`` (n, 3; NaN rows ignored) comes least near: the
    smallest largest |cosine| over its fields (minimax).

    A two-marker frame (:func:`axis_frames`) counts its turn from it. Chosen over the
    whole trial, not per span, so a fill and the stretches its error is measured on
    use one frame (per span a heel gap counted from the mediolateral direction, its
    stretches from the vertical: 0.8 mm expected, 13.6 true); minimax, not least on
    average, so the frame is defined wherever the axis goes.
    """
    unit = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    return np.eye(3)[int(np.argmin(np.nanmax(np.abs(unit), axis=0)))]


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
    both = np.isfinite(axis).all(axis=1)
    if not both.any():
        # The two donors are never measured together at ``f`` (a gap's ends and its
        # stretches' ends fall where a donor is missing too): no axis, no frame.
        return np.full_like(rel, np.nan)
    ref = np.eye(3)[int(np.argmin(np.abs(axis[both].mean(axis=0))))]
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


def across_joint(
    target: NDArray, dense: NDArray, donors: tuple[int, ...], floor: float
) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The two donors of the target's own segment and those across a joint, of a fill
    through three or more ``donors`` whose segment has only two (the neighbours
    :func:`~kisscal.tracking.bodyfill.segment_carriers` adds, most rigid first): those
    whose distance to the target or to either of the first two varies over the trial
    by more than ``floor`` mm (SD). ``(donors, ())`` when none is."""
    if len(donors) < 3:
        return donors, ()
    k = list(donors)
    sd = distance_stats(dense[k], np.stack([target, dense[k[0]], dense[k[1]]]))[2]
    soft = np.flatnonzero(sd[2:].max(axis=1) > floor) + 2
    if not soft.size or sd[:2, 0].max() > floor:
        return donors, ()
    return (donors[0], donors[1]), tuple(donors[i] for i in soft.tolist())


def phase_matched(
    stretches: list[tuple[int, int]],
    target: NDArray,
    dense: NDArray,
    donors: tuple[int, ...],
    gap: tuple[int, int],
    floor: float,
    split: tuple[tuple[int, ...], tuple[int, ...]] | None = None,
) -> list[tuple[tuple[int, int], float]]:
    """``stretches`` (pseudo-gaps, nearest first,
    :func:`~kisscal.tracking.stretches.pseudo_gaps`) in the order to measure a fill of
    ``gap`` (lo, hi) following ``donors`` on (the first two the fill can be made on),
    each with the factor its error is scaled up by.

    One or two donors do not fix their segment's turn about them (a heel about its
    ankle, or about the ankle-toe axis, as the foot rolls at heel strike); the fills
    carry the target across the gap from its place on each side (linearly, or by a cubic
    in the angle) and miss a share of a turn between the two, which stretches cut where
    the foot is flat do not show. So the stretches are taken in the same phase of the
    motion: those where the target moved in its donors' frame (:func:`moved`) most
    nearly as far as across the gap (by ratio; the nearer first among equals), their
    error scaled by ``(d_gap + floor) / (d_stretch + floor)`` where it moved less (a
    share of the turn; moves under ``floor`` mm are noise).

    Two donors of the segment and neighbours across a joint (:func:`across_joint`) fix
    the turn by the neighbours, as far as the joint holds still: the fill misses as the
    joint bends (lowcost 479: a toe carried by its heel and ankle and by the shank
    through a push-off, 1.7-2.9 mm expected from stretches of the flat foot, 7-12 mm
    off). So the phase is the joint's: how far the neighbours moved in the frame of the
    two (the most of them). With three donors or more of one segment (their frame turns
    with them), the two nearest, unscaled. ``split``: :func:`across_joint`'s result, when
    the caller has it."""
    core, joint = split if split is not None else across_joint(target, dense, donors, floor)
    if not stretches or not (1 <= len(donors) <= 2 or joint):
        return [(s, 1.0) for s in stretches[:2]]
    spans = np.array([gap, *stretches])
    if joint:
        far = np.max([moved(dense[j], dense, core, spans) for j in joint], axis=0)
    else:
        far = moved(target, dense, donors, spans)
    ratio = (far + floor) / floor
    ratio = ratio[0] / ratio[1:]
    best = np.argsort(np.abs(np.log(ratio)), kind="stable")
    return [(stretches[i], max(1.0, float(ratio[i]))) for i in best.tolist()]


def bridged(dense: NDArray, tracks: NDArray, fields: NDArray, reach: int) -> NDArray:
    """Positions (len(fields), len(tracks), 3) of ``tracks`` of ``dense`` at ``fields``:
    measured, or on the line between their samples on each side of a run of at most
    ``reach`` missing fields (a marker lost for a field or two is still there; its image
    merged into another's is often why it was lost); NaN elsewhere."""
    n = dense.shape[1]
    seen = np.isfinite(dense[tracks, :, 0])
    idx = np.arange(n)
    prev = np.maximum.accumulate(np.where(seen, idx, -1), axis=1)[:, fields].T
    nxt = np.minimum.accumulate(np.where(seen, idx, n)[:, ::-1], axis=1)[:, ::-1][:, fields].T
    ok = (prev >= 0) & (nxt < n) & (nxt - prev <= reach + 1)
    p, q = np.where(ok, prev, 0), np.where(ok, nxt, 0)
    w = ((fields[:, None] - p) / np.maximum(q - p, 1))[..., None]
    pts = dense[tracks[None], p] * (1 - w) + dense[tracks[None], q] * w
    return np.where(ok[..., None], pts, np.nan)


def _carried(dense: NDArray, t: int, partner: int, fields: NDArray, reach: int) -> NDArray:
    """Track ``t`` about at ``fields`` of its gap: ``partner`` (:func:`bridged` within
    ``reach``) plus the offset interpolated (a swinging foot strays from a line)."""
    n, one = dense.shape[1], np.array([0])
    got = bridged(dense[[partner]], one, fields, reach) + bridged(
        dense[[t]] - dense[[partner]], one, fields, n
    )
    return np.where(np.isfinite(got), got, bridged(dense[[t]], one, fields, n))[:, 0]


def shared_blobs(
    dense: NDArray,
    t: int,
    lo: int,
    ks: NDArray,
    rows: NDArray,
    spare: SpareBlobs,
    params: TrackingParams,
    partners: NDArray,
) -> NDArray[np.bool_]:
    """Which blobs ``rows`` (at gap offsets ``ks`` from ``lo``) may hold another track's
    image merged with the marker's: that track's image (:func:`bridged` within
    ``max_fill_gap_fields``) lies as near as a merged blob's centroid would. Such a blob
    lies off the marker's ray (lowcost 303: a heel's merged with its ankle's, placed 14 mm
    off), and two partners' lengths do not see it (their circle about the partners' axis
    meets a ray passed sideways along it). Images within ``ray_chain_gate_px`` make one
    blob at their centroid weighted by their areas (1 / depth²): the other's image lies
    at most ``ray_chain_gate_px * z_o² / (z_m² + z_o²)`` from it (``z_m``, ``z_o`` the
    distances from the camera, the marker carried by the partner of ``partners`` seen
    most beside it: :func:`_carried`),
    give or take three SDs of a blob's position (``ray_fill_px``). Farther, the blob is
    the marker's own, the other hidden from that camera or seen apart (lowcost 312: a
    toe's image 2.4 px from an ankle's own blob had cost a 1.5 mm fill)."""
    others = np.delete(np.arange(len(dense)), t)
    if rows.size == 0 or others.size == 0:
        return np.zeros(rows.size, dtype=bool)
    pts = bridged(dense, others, lo + ks, params.max_fill_gap_fields)  # (m, n_others, 3)
    seen = np.isfinite(dense[partners][:, max(lo - 1, 0) : lo + int(ks.max()) + 2, 0])
    partner = int(partners[np.argmax(seen.sum(axis=1))])
    own = _carried(dense, t, partner, lo + ks, params.max_fill_gap_fields)[:, None]
    centre = spare.centres[spare.camera[rows]][:, None]
    with np.errstate(invalid="ignore"):
        cams = np.repeat(spare.camera[rows], others.size)
        uv = project_rows(spare.dlts, cams, pts.reshape(-1, 3)).reshape(*pts.shape[:2], 2)
        z_o, z_m = (np.sum((p - centre) ** 2, axis=2) for p in (pts, own))
        share = np.where(np.isfinite(z_m), z_o / (z_m + z_o), 1.0)
        reach = params.ray_chain_gate_px * share + 3.0 * params.ray_fill_px
        near = np.linalg.norm(uv - spare.uv_px[rows][:, None], axis=2) <= reach
    if spare.track is not None:  # a point's image is no blob merged with that point's
        near &= spare.track[rows][:, None] != others[None]
    return np.any(near, axis=1)


def unshared(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    params: TrackingParams,
    partners: NDArray,
) -> SpareBlobs:
    """``spare`` with the blobs of fields [lo, hi) another track's image may share
    (:func:`shared_blobs`) no longer free: taken out
    before the marker's blob is followed in the image (a merged blob is not the
    marker's own image, nor a step of its path)."""
    rows = spare.rows(lo, hi)
    shared = shared_blobs(dense, t, lo, spare.field[rows] - lo, rows, spare, params, partners)
    free = spare.free.copy()
    free[rows[shared]] = False
    return dataclasses.replace(spare, free=free)


def padded_mirrors(mirror: NDArray | None, n: int) -> NDArray[np.int64]:
    """Each of ``n`` rows' mirror image's row: ``mirror`` cut or padded to ``n``, -1 for
    none (``mirror`` None, rows past its end) and for a mirror past ``n`` (a track list
    grows and shrinks while the mirror table is kept from the labels).

    Examples
    --------
    >>> padded_mirrors(np.array([2, 5, 0]), 4).tolist()
    [2, -1, 0, -1]
    """
    m = np.full(n, -1, dtype=np.int64) if mirror is None else np.r_[mirror, [-1] * n][:n]
    return np.where(m < n, m, -1).astype(np.int64)


def merged_edges(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    params: TrackingParams,
    partners: NDArray,
) -> list[int]:
    """The measured samples of track ``t`` at the edges of its gap [lo, hi) (fields
    ``lo - 1`` and ``hi``) one of whose blobs another track's image may share
    (:func:`shared_blobs`): the blob nearest the sample's image in each camera (within
    ``ray_chain_gate_px``; a point's image lies on its blobs but for their noise). Such
    a sample is pulled towards the other marker, and a spline through it carries that
    into the gap (lowcost 4 seed 437: an ankle's blob merged with the toe's in camera 1,
    the sample 23 mm off, its spline 24 mm RMS off expecting 6.1)."""
    out: list[int] = []
    if partners.size == 0:
        return out
    for f in (lo - 1, hi):
        if not 0 <= f < dense.shape[1] or not np.isfinite(dense[t, f, 0]):
            continue
        a, b = np.searchsorted(spare.field, [f, f + 1])
        rows = np.arange(a, b)
        if spare.point is not None:
            rows = rows[spare.point[rows] >= 0]
        if rows.size == 0:
            continue
        cams = spare.camera[rows]
        uv = project_rows(spare.dlts, cams, np.repeat(dense[t, f][None], rows.size, axis=0))
        dist = np.linalg.norm(uv - spare.uv_px[rows], axis=1)
        own = np.array([rows[cams == c][np.argmin(dist[cams == c])] for c in np.unique(cams)])
        own = own[dist[np.searchsorted(rows, own)] <= params.ray_chain_gate_px]
        ks = np.zeros(own.size, dtype=np.int64)
        if own.size and shared_blobs(dense, t, f, ks, own, spare, params, partners).any():
            out.append(f)
    return out
