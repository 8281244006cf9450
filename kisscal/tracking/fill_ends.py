"""Fill at a trajectory's ends: the fields before its first measured sample or after its
last, carried by the segment's other markers.

A marker whose cameras lose it at the start or the end of the trial while its segment's
other markers are still measured (a heel on the first fields of a walk, hidden until
heel strike) has no measured sample on one side: the gap fills, which bridge between
both sides, do not reach there. The segment carries it: its position in the frame of
three or more markers that keep their distances to it and to each other (SD over the
trial at most ``rigid_fill_sd_mm``), averaged over up to ``body_context_fields`` measured
samples beside the end, is held and carried by their motion (Kabsch's fit in each field)
for as long as all of them stay measured, ``max_body_fill_fields`` at most.

The fill is kept under the gap fills' guard: the same one-sided fill, run on stretches of
the marker's own measured samples (:func:`~kisscal.tracking.stretches.expected_errors`),
must miss them by at most ``max_body_fill_error_mm`` RMS.

References
----------
Challis 1995 (segments as rigid bodies of markers); Gløersen & Federolf 2016 (filling
from the other markers of the body); Kabsch 1976 (least-squares rotation).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import true_runs
from kisscal.dlt.model import project_rows, ray_directions
from kisscal.tracking.blob_paths import follow_blobs
from kisscal.tracking.bodyfill import (
    AXIS_MAX_COS,
    FillMethod,
    MutualSD,
    axis_frames,
    batch_kabsch,
    distance_sd,
    segment_carriers,
)
from kisscal.tracking.fill_donors import lab_reference
from kisscal.tracking.on_rays import MIN_RUN, ChainFill
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.raychain import chain_fill
from kisscal.tracking.rayfill import SpareBlobs
from kisscal.tracking.tracks import MEASURED, Tracks


def _window(target: NDArray, lo: int, hi: int, after: bool, n: int) -> NDArray[np.int64]:
    """Up to ``n`` measured fields of ``target`` just after ``hi`` (``after``) or just
    before ``lo``."""
    ok = np.all(np.isfinite(target), axis=1)
    return hi + np.flatnonzero(ok[hi:])[:n] if after else np.flatnonzero(ok[:lo])[-n:]


def _edge(window: NDArray, after: bool) -> int:
    """The field of the end next to the measured fields ``window`` (after it when
    ``after``, else before it)."""
    return int(window[0] - 1 if after else window[-1] + 1)


def end_donors(
    target: NDArray,
    dense: NDArray,
    exclude: int,
    window: NDArray,
    params: TrackingParams,
    edge: int,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Tracks that carry ``target`` beside its measured fields ``window`` (measured on at
    least two of them, and in the end's field ``edge`` next to them), and their weights,
    chosen as
    :func:`~kisscal.tracking.bodyfill.rigid_donors` chooses them across a gap: the
    segment (distances to the target and to each other within ``rigid_fill_sd_mm`` SD
    over the trial), most rigid first, weight 1; with two of them, neighbours across a
    joint (SD at most ``rigid_fill_neighbour_sd_mm``) weighing 1 / (1 + SD²). At most
    ``rigid_fill_markers``; the segment alone when it has two only and no neighbour."""
    none = np.zeros(0, dtype=np.int64), np.zeros(0)
    near = np.all(np.isfinite(dense[:, window]), axis=2).sum(axis=1) >= 2
    # A marker on two segments (an ankle: shank and foot) is carried by the one measured
    # where the end starts: chosen by rigidity alone, the other (lost there) carries
    # nothing, and which one wins may turn on a tenth of a millimetre of SD.
    near &= np.all(np.isfinite(dense[:, edge]), axis=1)
    near[exclude] = False
    cand = np.flatnonzero(near)
    if cand.size < 2:
        return none
    to_target = distance_sd(dense[cand], target[None])[:, 0]
    chosen, weight = segment_carriers(to_target, MutualSD(dense[cand]), params)
    if len(chosen) < 2:
        return none
    return cand[chosen].astype(np.int64), weight


def _local(
    frames: Callable[[NDArray], tuple[NDArray, NDArray]],
    target: NDArray,
    window: NDArray,
    params: TrackingParams,
) -> NDArray[np.float64] | None:
    """The target's mean position in the donors' frames (``frames(fields)``: rotations
    (n, 3, 3) and origins (n, 3)) over ``window``; None when it does not keep still in
    them (spread over ``rigid_fill_sd_mm``) or fewer than two fields have a frame."""
    r, t = frames(window)
    ok = np.all(np.isfinite(t), axis=1) & np.all(np.isfinite(r), axis=(1, 2))
    if ok.sum() < 2:
        return None
    local = np.einsum("nji,nj->ni", r[ok], target[window[ok]] - t[ok])
    if np.sqrt(np.sum(local.var(axis=0))) > params.rigid_fill_sd_mm:
        return None
    return local.mean(axis=0)


def one_sided(after: bool, axis: bool = False) -> FillMethod:
    """A fill method (the signature of :func:`~kisscal.tracking.bodyfill.rigid_fill`)
    that carries the target through [lo, hi) from its measured samples on one side only,
    after ``hi`` (``after``) or before ``lo``: in the frame of three or more donors
    (:func:`end_donors`, Kabsch's fit), or with ``axis`` of the segment's two markers and
    the lab direction least along them (as
    :func:`~kisscal.tracking.bodyfill.axis_fill`); None unless the donors are measured in
    every field of [lo, hi)."""

    def fill(
        target: NDArray, dense: NDArray, exclude: int, lo: int, hi: int, params: TrackingParams
    ) -> tuple[NDArray[np.float64], tuple[int, ...]] | None:
        window = _window(target, lo, hi, after, params.body_context_fields)
        if window.size < 2:
            return None
        donors, weight = end_donors(target, dense, exclude, window, params, _edge(window, after))
        if axis:
            donors, weight = donors[:2], weight[:2]
        if donors.size < (2 if axis else 3) or not np.all(np.isfinite(dense[donors, lo:hi])):
            return None
        frames = _axis_frames_of(dense, donors, lo, hi) if axis else None
        if axis and frames is None:
            return None
        if not axis:
            pts = dense[donors][:, window].transpose(1, 0, 2)
            seen = np.all(np.isfinite(pts), axis=(1, 2))
            if seen.sum() < 2:
                return None
            shape = pts[np.flatnonzero(seen)[0 if after else -1]]

            def frames(f: NDArray) -> tuple[NDArray, NDArray]:
                got = dense[donors][:, f].transpose(1, 0, 2)
                r = np.full((f.size, 3, 3), np.nan)
                t = np.full((f.size, 3), np.nan)
                ok = np.all(np.isfinite(got), axis=(1, 2))
                r[ok], t[ok] = batch_kabsch(shape, got[ok], weight)
                return r, t

        here = _local(frames, target, window, params)
        if here is None:
            return None
        r, t = frames(np.arange(lo, hi))
        return np.einsum("nij,j->ni", r, here) + t, tuple(int(d) for d in donors)

    return fill


def _axis_frames_of(dense: NDArray, pair: NDArray, lo: int, hi: int) -> Callable | None:
    """Frames of the two markers ``pair`` (:func:`~kisscal.tracking.bodyfill.axis_fill`'s)
    per field, their turn about the axis held by the lab direction it comes least near
    in the trial (:func:`~kisscal.tracking.fill_donors.lab_reference`); None when the
    axis turns towards it over [lo, hi) (cosine over ``AXIS_MAX_COS``).

    The trial's direction, not the end's: the stretches its expected error is measured
    on (:func:`~kisscal.tracking.stretches.expected_errors`) then use the frame the end
    is filled with (per span, few-camera rigs 301-313: an end fill 6.2 times worse than
    it expected; per trial, 3.3 at most).
    """
    ref = lab_reference(dense[pair[1]] - dense[pair[0]])
    axis = dense[pair[1], lo:hi] - dense[pair[0], lo:hi]
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    if np.abs(axis @ ref).max() > AXIS_MAX_COS:
        return None

    def frames(f: NDArray) -> tuple[NDArray, NDArray]:
        return axis_frames(dense[pair[0], f], dense[pair[1], f], ref), dense[pair[0], f]

    return frames


def end_carriers(
    dense: NDArray, t: int, lo: int, hi: int, after: bool, params: TrackingParams
) -> NDArray[np.int64]:
    """The donors (:func:`end_donors`) of the end [lo, hi) of track ``t`` beside its
    measured samples after ``hi`` when ``after``, else before ``lo``; none without two
    measured samples there."""
    window = _window(dense[t], lo, hi, after, params.body_context_fields)
    if window.size < 2:
        return np.zeros(0, dtype=np.int64)
    return end_donors(dense[t], dense, t, window, params, _edge(window, after))[0]


def end_reach(dense: NDArray, donors: NDArray, lo: int, hi: int, after: bool) -> int:
    """How many fields of the end [lo, hi) (beside measured samples after ``hi`` when
    ``after``, else before ``lo``) the ``donors`` (:func:`end_carriers`; at least two) are
    all measured in, counted from the measured side."""
    if donors.size < 2:
        return 0
    seen = np.all(np.isfinite(dense[donors, lo:hi]), axis=(0, 2))
    if after:
        seen = seen[::-1]
    lost = np.flatnonzero(~seen)
    return int(lost[0]) if lost.size else hi - lo


#: Largest distance (mm) of a point placed at an end from where the path, continued at
#: constant velocity from the fields before, expects it.
STEP_MM = 20.0


def _triangulate(c: NDArray, d: NDArray) -> tuple[NDArray[np.float64], float]:
    """Least-squares point of the rays ``c + s d`` (k, 3) and its largest distance to
    them (Hartley & Zisserman 2004)."""
    proj = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
    x = np.linalg.solve(proj.sum(axis=0), np.einsum("kij,kj->i", proj, c))
    return x, float(np.linalg.norm(np.einsum("kij,kj->ki", proj, x - c), axis=1).max())


def unmerged(
    spare: SpareBlobs, rows: NDArray, others: NDArray, near: NDArray, merge_px: float
) -> NDArray[np.float64]:
    """The images of blobs ``rows`` of a marker near ``near`` (3,) with the share of
    another marker's image taken out where one of ``others`` (m, 3; the other tracks
    there) projects within ``merge_px`` of the blob: a merged blob's centroid is the
    mean of the two images weighted by their areas, which fall with the square of the
    depth (:mod:`kisscal.recon.deblend`), so ``u = c + w (c - u_o)`` with ``w`` the
    other image's area over the marker's. Rows (k, 2)."""
    uv = spare.uv_px[rows]
    others = others[np.all(np.isfinite(others), axis=1)]
    if others.size == 0:
        return uv
    cam = spare.camera[rows]
    k, m = rows.size, len(others)
    proj = project_rows(spare.dlts, np.repeat(cam, m), np.tile(others, (k, 1))).reshape(k, m, 2)
    dist = np.linalg.norm(proj - uv[:, None], axis=2)
    o = dist.argmin(axis=1)
    lens = spare.dlts[cam, 8:11]
    own = lens @ near + 1.0  # DLT denominators: proportional to depth
    other = np.einsum("ij,ij->i", lens, others[o]) + 1.0
    w = (own / other) ** 2
    out = uv + w[:, None] * (uv - proj[np.arange(k), o])
    return np.where((dist.min(axis=1) <= merge_px)[:, None], out, uv)


def _meet(
    rows: NDArray, spare: SpareBlobs, uv: NDArray | None = None
) -> tuple[NDArray[np.float64], float, NDArray]:
    """The point where the rays of blobs ``rows`` (two or more; their images ``uv``,
    the blobs' own by default) meet best, its largest distance to them and the rows
    used: all of them, or of three or more, the subset without the one ray that misses
    the others most, when that is closer."""
    uv = spare.uv_px[rows] if uv is None else uv
    c = spare.centres[spare.camera[rows]]
    d = ray_directions(spare.dlts[spare.camera[rows]], uv)
    best = (*_triangulate(c, d), rows)
    if rows.size >= 3:
        for i in range(rows.size):
            keep = np.arange(rows.size) != i
            got = _triangulate(c[keep], d[keep])
            if got[1] < best[1]:
                best = (*got, rows[keep])
    return best


def _meet_unmerged(
    rows: NDArray, spare: SpareBlobs, own: NDArray
) -> tuple[NDArray[np.float64], float, NDArray]:
    """:func:`_meet` of the rays of blobs ``rows`` taken as they are or, each blob that
    another marker's image may share, through its image with that share taken out
    (``own``, :func:`unmerged`): of every such choice, the one whose rays meet best
    (another marker's image that near is not always merged with the marker's)."""
    may = np.flatnonzero(np.any(own != spare.uv_px[rows], axis=1))
    best = _meet(rows, spare)
    for pick in range(1, 2**may.size):
        uv = spare.uv_px[rows].copy()
        take = may[(pick >> np.arange(may.size)) & 1 == 1]
        uv[take] = own[take]
        got = _meet(rows, spare, uv)
        best = got if got[1] < best[1] else best
    return best


def rays_end_fill(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs | None,
    params: TrackingParams,
    end: int,
) -> ChainFill | None:
    """Fields of the end [lo, hi) of track ``t`` (``end`` -1: before its first measured
    sample, 1: after its last) where two or more cameras still see the marker: its blob
    followed in each camera's image from the trajectory's edge (as
    :func:`~kisscal.tracking.blob_paths.chain_blobs` follows it into a gap), the point
    where their rays meet, field by field out from the edge. A field is left out when it
    has fewer than two rays, the point is farther than ``ray_rest_max_error_mm`` from one
    of them (of three or more rays, the two or more that meet best are kept) or than
    :data:`STEP_MM` from the path continued at constant velocity; the walk stops after
    ``ray_chain_coast_fields`` such fields in a row. None when fewer than
    :data:`~kisscal.tracking.on_rays.MIN_RUN` fields are placed, or without ``spare``."""
    if spare is None:
        return None
    series = dense[t]
    edge, step = (hi, 1) if end < 0 else (lo - 1, -1)
    if not 0 <= edge + step < len(series) or not np.all(np.isfinite(series[[edge, edge + step]])):
        return None
    fields = np.arange(hi - 1, lo - 1, -1) if end < 0 else np.arange(lo, hi)
    rows = np.full((len(spare.dlts), hi - lo), -1)
    for cam in range(len(spare.dlts)):
        uv = project_rows(spare.dlts, [cam, cam], series[[edge, edge + step]])
        for f, row in follow_blobs(spare, cam, uv[0], uv[0] - uv[1], fields, params).items():
            rows[cam, f - lo] = row
    xyz, sd = np.full((hi - lo, 3), np.nan), np.full(hi - lo, np.nan)
    last, vel, since = series[edge], series[edge] - series[edge + step], 0
    merge = params.ray_merge_px
    for f in fields.tolist():
        r = rows[:, f - lo][rows[:, f - lo] >= 0]
        since += 1
        if since > params.ray_chain_coast_fields + 1:
            break
        if r.size < 2:
            continue
        own = unmerged(spare, r, np.delete(dense[:, f], t, axis=0), last + since * vel, merge)
        x, miss, used = _meet_unmerged(r, spare, own)
        if miss > params.ray_rest_max_error_mm or np.linalg.norm(x - last - since * vel) > STEP_MM:
            continue
        rows[:, f - lo][~np.isin(rows[:, f - lo], used)] = -1
        xyz[f - lo], sd[f - lo] = x, max(miss, params.ray_length_sd_floor_mm)
        last, vel, since = x, (x - last) / since, 0
    placed = np.isfinite(sd)
    if placed.sum() < MIN_RUN:
        return None
    taken = rows[:, placed]
    return ChainFill(xyz, sd, (), taken[taken >= 0].astype(np.int64))


def _edge_run(placed: NDArray, end: int) -> NDArray[np.bool_]:
    """Of the fields ``placed`` at a track's end (1: after its last sample, -1: before
    its first), the run next to the measured side, if at least
    :data:`~kisscal.tracking.on_rays.MIN_RUN` long."""
    seq = placed if end > 0 else placed[::-1]
    keep = np.zeros(seq.size, dtype=bool)
    lo, hi = true_runs(seq)
    if lo.size and lo[0] == 0 and hi[0] - lo[0] >= MIN_RUN:
        keep[lo[0] : hi[0]] = True
    return keep if end > 0 else keep[::-1]


def chain_end_fill(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs | None,
    params: TrackingParams,
    end: int,
    errors: NDArray | None = None,
    absent: NDArray | None = None,
    mirror: NDArray | None = None,
) -> ChainFill | None:
    """The end [lo, hi) of track ``t`` (``end`` as :func:`rays_end_fill`) that one
    camera still sees: the marker's blobs placed on their rays by its segment's lengths
    (:func:`~kisscal.tracking.raychain.chain_fill` walked from the measured side alone),
    with the checks a second side would give replaced by stricter ones: only fields
    where two or more partners are seen (their lengths over-determine the depth along
    the ray, and disagree on a wrong blob), and only the run next to the measured side
    (nothing checks a path that does not start at the sample it continues). None when
    nothing is placed, or without ``spare``. ``errors``, ``absent``, ``mirror``: as the
    chain fill's."""
    if spare is None:
        return None
    got = chain_fill(dense, t, lo, hi, spare, params, end, errors, absent, mirror)
    if absent is not None and len(absent):
        dense = np.concatenate([dense, absent])
    if got is None:
        return None
    placed = np.isfinite(got.sd_mm)
    seen = np.all(np.isfinite(dense[list(got.partners), lo:hi]), axis=2).sum(axis=0) >= 2
    keep = _edge_run(placed & seen, end)
    if not keep.any():
        return None
    xyz, sd = np.where(keep[:, None], got.xyz_mm, np.nan), np.where(keep, got.sd_mm, np.nan)
    return ChainFill(xyz, sd, got.partners, got.rows[keep[placed]])


def track_ends(
    tracks: Tracks, params: TrackingParams, labels: Sequence[str] | None, unlabelled: Sequence[int]
) -> list[tuple[int, int, int, int]]:
    """(track, first field, stop field, end) of the ends of each named track to fill:
    up to ``max_body_fill_fields`` fields before its first measured sample (end -1) and
    after its last (end 1), within the trial and short of any sample of another track
    of the same name; none when ``max_body_fill_fields`` is at most
    ``max_fill_gap_fields`` (the body's fills are off: every gap fill beyond the spline
    is)."""
    reach = params.max_body_fill_fields
    if labels is None or reach <= params.max_fill_gap_fields:
        return []
    meas = tracks.status == MEASURED
    n_fields = int(tracks.field.max()) + 1
    names = np.asarray(labels, dtype=object)
    out = []
    for t in sorted(set(range(tracks.n_tracks)) - set(unlabelled)):
        mf = tracks.field[meas & (tracks.track == t)]
        if mf.size == 0:
            continue
        others = tracks.field[(names[tracks.track] == names[t]) & (tracks.track != t)]
        lo = max(0, int(mf[0]) - reach, *(others[others < mf[0]] + 1).tolist())
        hi = min(n_fields, int(mf[-1]) + 1 + reach, *others[others > mf[-1]].tolist())
        out += [(t, lo, int(mf[0]), -1)] if lo < mf[0] else []
        out += [(t, int(mf[-1]) + 1, hi, 1)] if mf[-1] + 1 < hi else []
    return out
