"""Gap filling that uses the body: rigid-body fill and pattern fill, with expected errors.

A gap too long for a spline is filled from markers seen through it: **rigid-body fill**
(markers riding on the hidden one's segment carry it; its place in their frame is learnt
beside the gap, or from the static trial's template when the trial has none) or
**pattern fill** (it follows one neighbour's path). Each method's **expected error** is
measured by the same fill on stretches of the marker's own measured samples beside the
gap, and the smaller fills it: docs/methods.md, "Gap filling", tells each step.

Everything works on dense ``(n_tracks, n_fields, 3)`` arrays of measured positions (NaN
elsewhere); nothing knows about files.

References
----------
Kabsch 1976 (rotation between point sets); Challis 1995 (rigid-body estimation of
segment motion from markers); Gløersen & Federolf 2016 (gap filling from the other
markers of the body).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.fill_donors import axis_frames, distance_stats, lab_reference, sound_fill
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.stretches import FillMethod, expected_errors
from kisscal.tracking.tracks import FILLED_PATTERN, FILLED_RIGID


@dataclass(frozen=True)
class GapFill:
    """How one gap of one track was filled.

    Attributes
    ----------
    track : int
        Track number.
    first_field, n_fields : int
        The gap.
    status : int
        Status code of its samples (FILLED, FILLED_RIGID or FILLED_PATTERN).
    expected_error_mm : float
        RMS error of the same fill on stretches of the marker's own measured samples of
        the gap's length (NaN when there was no such stretch to try it on).
    donors : tuple of int
        Tracks the fill followed (none for the spline).
    ray_fields : int
        Fields of the gap moved onto the ray of a camera that still saw the marker
        (:mod:`kisscal.tracking.rayfill`); ``expected_error_mm`` is then the fill's error
        along that camera's line of sight.
    """

    track: int
    first_field: int
    n_fields: int
    status: int
    expected_error_mm: float
    donors: tuple[int, ...] = ()
    ray_fields: int = 0


def batch_kabsch(
    source: NDArray, target: NDArray, weight: NDArray | None = None
) -> tuple[NDArray, NDArray]:
    """Proper rotations and translations mapping ``source`` (k, 3) onto each of
    ``target`` (n, k, 3) in the weighted least-squares sense: r (n, 3, 3), t (n, 3), with
    ``target ~ source @ r.T + t``; ``weight`` (k,) per point (default equal).

    References
    ----------
    Kabsch 1976.
    """
    w = np.ones(len(source)) if weight is None else np.asarray(weight, dtype=float)
    w = w / w.sum()
    cs = w @ source
    ct = np.einsum("k,nkj->nj", w, target)
    h = np.einsum("k,ki,nkj->nij", w, source - cs, target - ct[:, None, :])
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(np.transpose(vt, (0, 2, 1)) @ np.transpose(u, (0, 2, 1))))
    d[d == 0] = 1.0
    fix = np.ones((len(d), 3))
    fix[:, 2] = d
    r = np.transpose(vt, (0, 2, 1)) @ (fix[:, :, None] * np.transpose(u, (0, 2, 1)))
    return r, ct - np.einsum("nij,j->ni", r, cs)


def _carriers(
    target: NDArray,
    dense: NDArray,
    exclude: int,
    lo: int,
    hi: int,
    params: TrackingParams,
    fewest: int,
) -> tuple[NDArray[np.int64], NDArray[np.float64], tuple[NDArray, NDArray]] | None:
    """Markers that could carry ``target`` across the gap [lo, hi): seen through it and on
    at least two fields of each side's window, with the SD of their distance to the target
    over the trial, and the two windows (:func:`side_windows`); None when the target's windows
    or fewer than ``fewest`` markers allow no fill."""
    before, after = side_windows(target, lo, hi, params.body_context_fields)
    if before.size < 2 or after.size < 2:
        return None
    through = np.all(np.isfinite(dense[:, lo:hi]), axis=(1, 2))
    through[exclude] = False
    cand = np.flatnonzero(through)
    near = np.all(np.isfinite(dense[cand]), axis=2)
    cand = cand[(near[:, before].sum(axis=1) >= 2) & (near[:, after].sum(axis=1) >= 2)]
    if cand.size < fewest:
        return None
    return cand, distance_sd(dense[cand], target[None])[:, 0], (before, after)


def side_windows(series: NDArray, lo: int, hi: int, n: int) -> tuple[NDArray, NDArray]:
    """Fields of up to ``n`` measured samples of ``series`` just before ``lo`` and just
    after ``hi`` (exclusive)."""
    ok = np.all(np.isfinite(series), axis=1)
    before = np.flatnonzero(ok[:lo])[-n:]
    after = hi + np.flatnonzero(ok[hi:])[:n]
    return before, after


def ramp(lo: int, hi: int) -> NDArray[np.float64]:
    """Weight of the after-side across the gap fields lo..hi-1 (0 near lo, 1 near hi)."""
    return (np.arange(lo, hi) - lo + 1.0) / (hi - lo + 1.0)


def distance_sd(a: NDArray, b: NDArray) -> NDArray[np.float64]:
    """SD (mm) over the trial of the distance between each series of ``a`` (k, n, 3) and
    each of ``b`` (m, n, 3), over the fields where both are measured: (k, m); inf with
    fewer than 4 such fields (:func:`~.fill_donors.distance_stats`)."""
    return distance_stats(a, b)[2]


class MutualSD:
    """:func:`distance_sd` of ``series`` (c, n, 3) to each other, as ``[rows, columns]``
    of a (c, c) matrix whose columns are computed when first read: :func:`segment_carriers`
    reads those of the segment only, and all c x c pairs over a long trial took most of a
    re-track's time (FunctionalWalk, BTKData)."""

    def __init__(self, series: NDArray) -> None:
        self.series, self.done = series, {}

    def __getitem__(self, key: tuple) -> NDArray[np.float64]:
        rows, cols = key
        for j in set(cols) - self.done.keys():
            self.done[j] = distance_sd(self.series, self.series[j : j + 1])[:, 0]
        return np.array([self.done[j] for j in cols]).reshape(len(cols), len(self.series)).T[rows]


def rigid_donors(
    target: NDArray, dense: NDArray, exclude: int, lo: int, hi: int, params: TrackingParams
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Markers that carry ``target`` through the gap [lo, hi), and their weights: of the
    :func:`_carriers`, those :func:`segment_carriers` chooses (SDs over the whole trial,
    since a joint may stay still beside a gap); none when fewer than three carry it."""
    none = np.zeros(0, dtype=np.int64), np.zeros(0)
    carriers = _carriers(target, dense, exclude, lo, hi, params, 3)
    if carriers is None:
        return none
    cand, to_target, _ = carriers
    chosen, weight = segment_carriers(to_target, MutualSD(dense[cand]), params)
    if len(chosen) < 3:
        return none
    return cand[chosen], weight


def segment_carriers(
    to_target: NDArray, mutual: MutualSD, params: TrackingParams
) -> tuple[list[int], NDArray[np.float64]]:
    """Which candidates carry a target, and their weights, from their distance SDs (mm)
    to the target ``to_target`` (c,) and to each other ``mutual`` (c, c).

    The segment: candidates within ``rigid_fill_sd_mm`` of the target and of each other,
    most rigid first, weight 1. With only two of them, neighbours across a joint (SD at
    most ``rigid_fill_neighbour_sd_mm`` to the segment and the target) weigh
    1 / (1 + SD²). At most ``rigid_fill_markers`` in all; none when fewer than two form
    the segment.
    """
    core: list[int] = []
    for i in np.argsort(to_target).tolist():
        if to_target[i] <= params.rigid_fill_sd_mm and np.all(
            mutual[i, core] <= params.rigid_fill_sd_mm
        ):
            core.append(i)
    if len(core) < 2:
        return [], np.zeros(0)
    core = core[: params.rigid_fill_markers]
    if len(core) >= 3:
        return core, np.ones(len(core))
    soft = np.maximum(to_target, mutual[:, core].max(axis=1))
    soft[core] = np.inf
    extra = [i for i in np.argsort(soft).tolist() if soft[i] <= params.rigid_fill_neighbour_sd_mm]
    extra = extra[: params.rigid_fill_markers - 2]
    return core + extra, np.concatenate([[1.0, 1.0], 1.0 / (1.0 + soft[extra] ** 2)])


def rigid_fill(
    target: NDArray, dense: NDArray, exclude: int, lo: int, hi: int, params: TrackingParams
) -> tuple[NDArray[np.float64], tuple[int, ...]] | None:
    """Fill fields [lo, hi) of ``target`` from three or more rigid partners
    (:func:`rigid_donors`): its place in their frame is averaged over each side and drifts
    linearly across the gap."""
    donors, weight = rigid_donors(target, dense, exclude, lo, hi, params)
    if donors.size < 3:
        return None
    before, after = side_windows(target, lo, hi, params.body_context_fields)
    local = []
    shape = None
    for side in (before, after):
        pts = dense[donors][:, side].transpose(1, 0, 2)  # (n, k, 3)
        ok = np.all(np.isfinite(pts), axis=(1, 2))
        if ok.sum() < 2:
            return None
        if shape is None:
            shape = pts[np.flatnonzero(ok)[-1]]
        r, t = batch_kabsch(shape, pts[ok], weight)
        local.append(np.einsum("nji,nj->ni", r, target[side[ok]] - t).mean(axis=0))
    r, t = batch_kabsch(shape, dense[donors][:, lo:hi].transpose(1, 0, 2), weight)
    w = ramp(lo, hi)[:, None]
    here = local[0] * (1 - w) + local[1] * w
    return np.einsum("nij,nj->ni", r, here) + t, tuple(int(d) for d in donors)


#: Two-marker fill: largest cosine between the markers' axis and the lab direction that
#: settles the frame's turn about it (a foot pitching at toe-off swings its axis up).
AXIS_MAX_COS = 0.7


def rigid_pair(
    dense: NDArray, cand: NDArray, to_target: NDArray, params: TrackingParams
) -> NDArray | None:
    """The two of ``cand`` whose distance to the target (SD ``to_target``) holds best,
    or None when theirs, or their own to each other, varies more than
    ``rigid_fill_sd_mm``: a segment's axis to carry the target about."""
    order = np.argsort(to_target)[:2]
    pair = cand[order]
    limit = params.rigid_fill_sd_mm
    if (
        to_target[order].max() > limit
        or distance_sd(dense[pair[:1]], dense[pair[1:]])[0, 0] > limit
    ):
        return None
    return pair


def axis_fill(
    target: NDArray, dense: NDArray, exclude: int, lo: int, hi: int, params: TrackingParams
) -> tuple[NDArray[np.float64], tuple[int, ...]] | None:
    """Fill fields [lo, hi) of ``target`` from the two markers that keep their distances
    to it and to each other best (SD over the trial at most ``rigid_fill_sd_mm``: its
    segment's), measured through the gap: the target's position in their frame
    (:func:`axis_frames`, turning with the lab direction their axis comes least near in
    the trial) is averaged over each side and drifts linearly across the gap: a segment
    with two markers in view (a shank) turns little about their axis."""
    carriers = _carriers(target, dense, exclude, lo, hi, params, 2)
    if carriers is None:
        return None
    cand, to_target, (before, after) = carriers
    pair = rigid_pair(dense, cand, to_target, params)
    if pair is None:
        return None
    # the trial's reference, not the span's: expected_errors' stretches use the gap's frame
    ref = lab_reference(dense[pair[1]] - dense[pair[0]])
    axis = dense[pair[1], lo:hi] - dense[pair[0], lo:hi]
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    if np.abs(axis @ ref).max() > AXIS_MAX_COS:
        return None  # the axis turns towards the lab direction: the frame's turn is lost
    local = []
    for side in (before, after):
        ok = np.all(np.isfinite(dense[pair][:, side]), axis=(0, 2))
        if ok.sum() < 2:
            return None
        f = side[ok]
        r = axis_frames(dense[pair[0], f], dense[pair[1], f], ref)
        here = np.einsum("nji,nj->ni", r, target[f] - dense[pair[0], f])
        if np.sqrt(np.sum(here.var(axis=0))) > params.rigid_fill_sd_mm:
            return None  # the frame does not hold the target still beside the gap
        local.append(here.mean(axis=0))
    r = axis_frames(dense[pair[0], lo:hi], dense[pair[1], lo:hi], ref)
    w = ramp(lo, hi)[:, None]
    here = local[0] * (1 - w) + local[1] * w
    return np.einsum("nij,nj->ni", r, here) + dense[pair[0], lo:hi], tuple(int(d) for d in pair)


def pattern_fill(
    target: NDArray, dense: NDArray, exclude: int, lo: int, hi: int, params: TrackingParams
) -> tuple[NDArray[np.float64], tuple[int, ...]] | None:
    """Fill fields [lo, hi) of ``target`` by following the neighbour whose offset from it
    changes least across the context (see module); the offset drifts linearly from its
    value at the last field before the gap to its value at the first after."""
    if lo < 1 or hi >= len(target):
        return None
    through = np.all(np.isfinite(dense[:, lo - 1 : hi + 1]), axis=(1, 2))
    through[exclude] = False
    cand = np.flatnonzero(through)
    if cand.size == 0:
        return None
    before, after = side_windows(target, lo, hi, params.body_context_fields)
    if before.size < 2 or after.size < 2 or before[-1] != lo - 1 or after[0] != hi:
        return None
    off_b = target[lo - 1] - dense[cand, lo - 1]
    off_a = target[hi] - dense[cand, hi]
    # the neighbour whose offset moves least over the gap, per field crossed, and within
    # each side (its pattern is the target's)
    wobble = np.linalg.norm(off_a - off_b, axis=1)
    for side in (before, after):
        step = np.linalg.norm(np.diff(target[side][None] - dense[cand][:, side], axis=1), axis=2)
        n = np.isfinite(step).sum(axis=1)
        mean = np.where(n > 0, np.nansum(step, axis=1) / np.maximum(n, 1), np.inf)
        wobble = wobble + mean * (hi - lo)
    best = int(np.argmin(wobble))
    if not np.isfinite(wobble[best]):
        return None
    d = cand[best]
    w = ramp(lo, hi)[:, None]
    offset = off_b[best] * (1 - w) + off_a[best] * w
    return dense[d, lo:hi] + offset, (int(d),)


#: What a gap longer than ``max_fill_gap_fields`` may be filled with. Not the spline:
#: beyond a few fields it misses a heel strike's stop, and its error measured beside the
#: gap does not tell (a 7-field heel gap: 3 mm expected, 16 mm true).
BODY_METHODS: tuple[tuple[int, FillMethod], ...] = (
    (FILLED_RIGID, rigid_fill),
    (FILLED_RIGID, axis_fill),
    (FILLED_PATTERN, pattern_fill),
)


@dataclass(frozen=True)
class Candidate:
    """One method's fill of a gap: positions, how (with its expected error), and its
    expected error along a camera's line of sight (NaN when not asked for)."""

    xyz_mm: NDArray[np.float64]
    fill: GapFill
    along_sight_mm: float


def _pattern_errors(
    target: NDArray,
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    params: TrackingParams,
    centres: NDArray | None,
    donors: tuple[int, ...],
) -> tuple[float, float]:
    """A pattern fill's :func:`~.stretches.expected_errors` (whole, along the sight) following its
    neighbour (:func:`followed`): on the two stretches nearest the gap's phase, or on
    all of the first :data:`~.stretches.SPREAD_STRETCHES` where more. Two may miss how far the
    offset strays from a line over the motion (lowcost seed 311: a thigh following the
    pelvis, 3.9 mm on two, 9.2 on six, 6.6 mm off), six may dilute it (modern 3 seed
    301: a knee following the thigh, 3.7 on two, 2.9 on six, 3.4 mm off)."""
    src = followed(dense, t, donors)
    near = expected_errors(pattern_fill, target, src, t, lo, hi, params, centres, donors)
    phase = expected_errors(pattern_fill, target, src, t, lo, hi, params, centres, donors, True)
    return float(np.fmax(near[0], phase[0])), float(np.fmax(near[1], phase[1]))


def followed(dense: NDArray, t: int, donors: tuple[int, ...]) -> NDArray:
    """``dense`` with only track ``t`` and its fill's ``donors`` kept (NaN elsewhere): a
    pattern fill free to take any neighbour on the stretches beside the gap takes the
    one that follows the marker there, which tells nothing of the one it followed
    across the gap (lowcost seed 311: an ankle following the thigh expected 2.4 mm,
    8.3 mm off; following the thigh on a stretch of the trial, 25 mm)."""
    out = np.full_like(dense, np.nan)
    keep = [t, *donors]
    out[keep] = dense[keep]
    return out


def fill_candidates(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    params: TrackingParams,
    methods: tuple[tuple[int, FillMethod], ...] = BODY_METHODS,
    centres: NDArray | None = None,
) -> list[Candidate]:
    """Every fill of the gap [lo, hi) of track ``t`` that one of ``methods`` makes through
    donors that hold their shape in the gap (:func:`donors_hold`), with its
    :func:`~.stretches.expected_errors` (along the sight of the cameras at ``centres`` too; a
    pattern fill's following its one neighbour, :func:`_pattern_errors`). Where
    three donors or more do not hold and the misfit is one's (:func:`out_of_shape`), the
    method is made again without it (lowcost 312: a toe 5 mm off in an ankle's gap cost
    a 1.5 mm fill from the three others)."""
    target = dense[t]
    out = []
    for status, method in methods:
        got, src = sound_fill(method, dense, t, lo, hi, params)
        if got is None:
            continue
        measure = _pattern_errors if method is pattern_fill else partial(expected_errors, method)
        err, along = measure(target, src, t, lo, hi, params, centres, got[1])
        out.append(Candidate(got[0], GapFill(t, lo, hi - lo, status, err, got[1]), along))
    return out


def best_candidate(cands: list[Candidate], params: TrackingParams) -> Candidate | None:
    """The candidate of smallest expected error, if at most ``max_body_fill_error_mm``."""
    ok = [c for c in cands if c.fill.expected_error_mm <= params.max_body_fill_error_mm]
    return min(ok, key=lambda c: c.fill.expected_error_mm) if ok else None
