"""Gap filling of final trajectories (smoothing is :mod:`kisscal.tracking.smooth`'s).

Gaps inside a trajectory (blended gaps, and coasted fields whose Kalman prediction is
replaced by a two-sided estimate) are filled by a cubic interpolating spline through the
measured samples on both sides when short, and from the body (rigid-body or pattern fill,
:mod:`kisscal.tracking.bodyfill`; about two markers' axis, :mod:`kisscal.tracking.fill_hinge`)
when longer, and on the rays of blobs a camera still sees (:data:`FILLS` gives the order).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Sequence
from functools import partial

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import true_runs
from kisscal.tracking.bodyfill import GapFill, best_candidate, fill_candidates
from kisscal.tracking.fill_absent import absent_named, absent_rows, mirror_tracks
from kisscal.tracking.fill_anchor import anchored, body_donors, donor_errors, donor_noise
from kisscal.tracking.fill_centre import centre_body
from kisscal.tracking.fill_depth import depth_ray_fill
from kisscal.tracking.fill_ends import (
    chain_end_fill,
    end_reach,
    one_sided,
    rays_end_fill,
    track_ends,
)
from kisscal.tracking.fill_held import held_body
from kisscal.tracking.fill_hinge import HINGE_METHODS
from kisscal.tracking.fill_hip import hip_ray_fill
from kisscal.tracking.fill_joint import joint_ray_fill
from kisscal.tracking.fill_joint_depth import joint_depth_fill
from kisscal.tracking.fill_pair import merged_pair_fill
from kisscal.tracking.fill_place import at_least, placed_mask, take_placed, with_rays
from kisscal.tracking.fill_sphere import sphere_depth_fill
from kisscal.tracking.fill_spline import context_noise, sight_noise, spline_fill, unpulled
from kisscal.tracking.fill_table import Fill, hole_length
from kisscal.tracking.fill_trusted import TRUSTED_PASS, context
from kisscal.tracking.fill_unmerged import unmerged_depth_fill
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.raychain import chain_fill, parted
from kisscal.tracking.rayfill import SpareBlobs, freed
from kisscal.tracking.tracks import FILLED, FILLED_RIGID, MEASURED, PREDICTED, Tracks, is_filled


def _track_gaps(tracks: Tracks, rows: slice, params: TrackingParams) -> list[tuple[int, int]]:
    """(first field, stop field) of each gap of one track's ``rows`` to fill."""
    f = tracks.field[rows]
    status = tracks.status[rows]
    meas = status == MEASURED
    mf = f[meas]
    f0, f1 = mf[0], mf[-1]
    kept = meas | is_filled(status)
    if not params.refill_predicted:
        kept |= status == PREDICTED
    covered = np.zeros(f1 - f0 + 1, dtype=bool)
    inside = (f >= f0) & (f <= f1)
    covered[f[kept & inside] - f0] = True
    gap_lo, gap_hi = true_runs(~covered)
    longest = max(params.max_fill_gap_fields, params.max_body_fill_fields)
    return [
        (int(lo + f0), int(hi + f0))
        for lo, hi in zip(gap_lo.tolist(), gap_hi.tolist(), strict=True)
        if hi - lo <= longest
    ]


@dataclasses.dataclass
class _Gap:
    """One gap [lo, hi) of track ``t`` being filled: ``swept`` marks the fields placed by
    the sweeping fills, ``out`` collects the fills made. ``measured`` (n_fields,) bool:
    the track's measured fields (for the depth fill's spline). ``end``: 0 for a gap
    inside the track, -1 for the fields before its first measured sample, 1 after its
    last. ``absent``: rows of markers no track took (:mod:`.fill_absent`), joint fills.
    ``known`` (n_tracks, n_fields) bool: every track's measured samples (the second
    passes': the sphere fill counts a placed partner's error). ``expected`` (n_tracks,
    n_fields): the error of each track's known samples, NaN where none (the last
    pass's, :mod:`.fill_unmerged`). ``errors`` (n_tracks + len(absent), n_fields):
    every sample's expected error (0 measured, a fill's as it is made, :func:`_note`,
    the ``absent`` rows' along their rays; NaN where none), for the chain fill's
    placed partners."""

    dense: NDArray
    t: int
    lo: int
    hi: int
    params: TrackingParams
    spare: SpareBlobs | None
    measured: NDArray | None
    swept: NDArray
    out: list
    end: int = 0
    absent: NDArray | None = None
    known: NDArray | None = None
    expected: NDArray | None = None
    errors: NDArray | None = None
    mirror: NDArray | None = None


def _ray_placer(method: Callable, *extra: str) -> Callable:
    """A fill of :data:`FILLS` from a single-camera placer ``method(dense, t, a, b, spare,
    params, *extra)`` (a :class:`ChainFill` or None; ``extra`` names attributes of the
    gap): its fields written as context, their blobs taken (:func:`take_placed`)."""

    def fill(gap: _Gap, a: int, b: int, params: TrackingParams) -> NDArray[np.bool_]:
        got = method(gap.dense, gap.t, a, b, gap.spare, params, *(getattr(gap, n) for n in extra))
        if got is None:
            return np.zeros(b - a, dtype=bool)
        gap.out.extend(take_placed(gap.dense, gap.t, a, got, gap.spare))
        return np.isfinite(got.sd_mm)

    return fill


def _body(
    gap: _Gap, a: int, b: int, params: TrackingParams, spline: bool = True, checked: bool = False
) -> NDArray[np.bool_]:
    """Spline for short runs (unless not ``spline``), the body (:func:`best_candidate`)
    for longer ones, as a fill of :data:`FILLS` expecting at least the error of the gap's
    fills it reads (:func:`anchored`); with spare blobs, each filled field a camera still
    sees moved onto its ray (:func:`with_rays`); no spline where the marker's blobs
    followed in the image from the two sides part (:func:`~kisscal.tracking.raychain.parted`).
    A spline expects at least what the noise of the samples it goes through carries
    (:func:`~kisscal.tracking.fill_spline.context_noise`; lowcost 301-313: 98 samples over
    twice their spline's expected error, the stretches it is tried on quieter); moved
    onto a ray, what of that noise lies along the sight of the cameras whose blobs it
    looked for (:func:`~kisscal.tracking.fill_spline.sight_noise`). With
    ``checked``, a spline is kept only when, counting the largest expected error of the
    samples it reads too (``gap.errors``), it expects at most ``max_body_fill_error_mm``
    (else the body: kiss 3 seed 303's toe, 5 fields beside a chain fill, left open)."""
    none = np.zeros(b - a, dtype=bool)
    hole = hole_length(gap.dense[gap.t], a, b)  # what a spline bridges, not the run alone
    short = (spline or checked) and hole <= params.max_fill_gap_fields
    if not short and b - a > params.max_body_fill_fields:
        return none
    spare = gap.spare
    rays = spare is not None and spare.rows(a, b).size > 0
    methods = ((FILLED, spline_fill),) if short else HINGE_METHODS
    centres = spare.centres if rays else None
    body = unpulled(body_donors(gap, params), gap, a, b, params, short and rays)
    cands = fill_candidates(body, gap.t, a, b, params, methods, centres)
    chosen = cands[0] if short and cands else best_candidate(cands, params)
    # a spline has no error of its own to check: between samples the marker's own image
    # does not join, it may bridge to another marker's
    if chosen is None or (short and rays and parted(gap.dense[gap.t], a, b, spare, params)):
        return _body(gap, a, b, params, spline=False) if checked and short else none
    seen = spare.centres[np.unique(spare.camera[spare.rows(a, b)])] if rays else None
    got = with_rays(chosen, spare, params) if rays else [(chosen.xyz_mm, chosen.fill)]
    if short:  # after the rays (their gate is the stretches' error): through noisy samples
        n = max(params.fill_context_fields, 2)
        noise = context_noise(body[gap.t], None, a, b, n)
        along = sight_noise(body[gap.t], seen, a, b, n) if rays else noise
        got = [(x, at_least(f, along if f.ray_fields else noise)) for x, f in got]
        if checked:
            near = gap.errors[gap.t, max(a - n, 0) : b + n] if gap.errors is not None else []
            got = [(x, at_least(f, float(np.nanmax(np.r_[near, 0.0])))) for x, f in got]
            worst = np.max([f.expected_error_mm for _, f in got] or [np.inf])
            if not worst <= params.max_body_fill_error_mm:  # NaN: nothing to check it by
                return _body(gap, a, b, params, spline=False)  # the body, as without
    got = donor_errors(donor_noise(got, gap.dense), gap.errors)
    gap.out.extend(anchored(got, gap.out, params.fill_context_fields))
    return placed_mask(got, a, b)


def _end(gap: _Gap, a: int, b: int, params: TrackingParams) -> NDArray[np.bool_]:
    """The fields of the end [a, b) of a track next to its measured samples that its
    segment carries (:mod:`kisscal.tracking.fill_ends`): as far as all its donors are
    measured, by them or by its two most rigid markers; then as far as those two are,
    by them; each kept when its expected error is at most ``max_body_fill_error_mm``,
    moved onto the rays of blobs a camera still sees there (:func:`with_rays`) and
    written into ``gap.dense`` (the edge the one-camera fill beyond walks from)."""
    placed = np.zeros(b - a, dtype=bool)
    after = gap.end < 0
    rigid, axis = (FILLED_RIGID, one_sided(after)), (FILLED_RIGID, one_sided(after, axis=True))
    done = 0
    for k, methods in ((params.rigid_fill_markers, (rigid, axis)), (2, (axis,))):
        n = end_reach(gap.dense, gap.t, a, b, after, params, k)
        if n <= done:
            continue
        lo, hi = (b - n, b - done) if after else (a + done, a + n)
        rays = gap.spare is not None and gap.spare.rows(lo, hi).size > 0
        centres = gap.spare.centres if rays else None
        cands = fill_candidates(body_donors(gap, params), gap.t, lo, hi, params, methods, centres)
        chosen = best_candidate(cands, params)
        if chosen is None:
            break
        got = with_rays(chosen, gap.spare, params) if rays else [(chosen.xyz_mm, chosen.fill)]
        gap.out.extend(donor_errors(donor_noise(got, gap.dense), gap.errors))
        placed[lo - a : hi - a] = mine = placed_mask(got, lo, hi, gap.dense[gap.t])
        if not mine.all():
            break  # its rays refused part of it: what lies beyond has no edge to walk from
        done = n
    return placed


#: The fills of a gap, in order: each is tried on the fields the ones before it left
#: (see :class:`Fill` for the reach of each). The marker's own blobs placed on their rays
#: by the segment's lengths to its measured markers (:func:`~.raychain.chain_fill`), then
#: with the segment's other markers on theirs (:func:`~.fill_joint.joint_ray_fill`); then
#: the spline (short runs) or the body (:func:`_body`), only expecting little error
#: (``ray_rest_max_error_mm``) between fields placed on rays; where it finds none, the
#: blobs of one camera at a spline's distance from it (:func:`~.fill_depth.depth_ray_fill`),
#: or at the depth fitted to that spline and the segment's lengths together
#: (:func:`~.fill_sphere.sphere_depth_fill`), the body about a marker and a joint centre
#: (:func:`~.fill_centre.centre_body`), and the fields left between them by the body
#: expecting little error. At a named track's ends, once every gap is filled: the point
#: where two or more cameras' rays of the marker's blobs meet
#: (:func:`~.fill_ends.rays_end_fill`), the fields it left between them as a gap
#: (:func:`_body`), the segment carrying it from one side (:func:`_end`), then beyond, its
#: blobs in one camera placed on their rays by its segment's lengths
#: (:func:`~.fill_ends.chain_end_fill`; after the segment, which carried kiss 3 seed 303's
#: LTIB to 0.6 mm where one camera's ray took it to 2.3). Fields placed on rays have status
#: ``filled_rigid``, every one counted in ``ray_fields``.
#: Between the two, once every track's gaps are filled, and again after the ends, the
#: fields they left are tried again with the partners placed since
#: (:func:`_second_pass`: a tibia hidden from every camera while the knee, seen by one,
#: is placed only at its track's end).
FILLS: tuple[Fill, ...] = (
    Fill(
        "chain", _ray_placer(chain_fill, "end", "errors", "absent", "mirror"), sweep=True, rays=True
    ),
    Fill("joint", _ray_placer(joint_ray_fill, "absent", "mirror"), sweep=True, rays=True),
    Fill("body", _body, strict="swept"),
    Fill("body where donors hold", held_body, long_run=True, strict="swept"),
    Fill("depth", _ray_placer(depth_ray_fill, "measured"), rays=True, long_run=True),
    Fill(
        "sphere depth",
        _ray_placer(sphere_depth_fill, "measured", "known", "expected", "mirror"),
        rays=True,
        long_run=True,
    ),
    Fill("body about a joint centre", centre_body, long_run=True, strict="swept"),
    Fill("body between rays", _body, split_only=True, strict="always"),
    Fill("end rays", _ray_placer(rays_end_fill, "end"), ends=True),
    Fill("end holes", _body, ends=True, enclosed=True),
    Fill("end", _end, ends=True),
    Fill("end chain", _ray_placer(chain_end_fill, "end", "errors", "absent", "mirror"), ends=True),
)


#: The fills of the second pass (:func:`_second_pass`): the marker's own blobs placed on
#: their rays by its segment's lengths, or at a smooth depth through the joint fill's
#: loose solutions (:mod:`.fill_joint_depth`; only what all else left: in the first pass
#: it took lowcost 311 RTOE, 6.7 mm off expecting 1.6), the rest by the body expecting
#: little error, a spline only where it expects little error too, counting the samples
#: it reads and their noise (:func:`_body`'s ``checked``; these runs lie beside what
#: the first pass's checks refused: lowcost 303 RANK, a spline to a wrong sample 49 mm off).
SECOND_PASS = (
    *(f for f in FILLS if f.name in ("chain", "joint")),
    Fill(
        "joint depth",
        _ray_placer(joint_depth_fill, "measured", "absent", "mirror"),
        rays=True,
        long_run=True,
    ),
    Fill("body", partial(_body, checked=True), strict="always"),
)

#: The last pass, after the ends: :data:`SECOND_PASS`, then on what it left the depth fitted to the
#: spline and the lengths of the partners placed since, their error counted, as their fills expect
#: it where two partners check each other (:mod:`.fill_sphere`; lowcost 306 LTHI: one camera, its
#: knee placed, the pelvis's sacrum only at its track's end, 0.9 mm expected: at
#: ``ray_rest_max_error_mm`` each, 39-44 expected 3.2-3.7 mm, 0.5-1.7 mm off, and stayed open). Not
#: before: a run it splits is walked by the chain fill from a placed edge (kiss 3 seed 306 RTIB, 4.6
#: mm RMS off expecting 2.7), and before the body it took lowcost 311 RANK on the toe's sphere 19.7
#: mm off. Then the marker solved with the pelvis carrying its hip centre on rays
#: (:mod:`.fill_hip`); last, the same depth on the rays of blobs merged with a neighbour placed by
#: then, its share out (:mod:`.fill_unmerged`), then both (:mod:`.fill_pair`), on any run (lowcost
#: 311, 361).
LAST_PASS = (
    *SECOND_PASS,
    *(f for f in FILLS if f.name == "sphere depth"),
    Fill("hip", _ray_placer(hip_ray_fill, "absent", "mirror", "errors"), rays=True, long_run=True),
    Fill("unmerged", _ray_placer(unmerged_depth_fill, "measured", "known", "expected", "mirror")),
    Fill("merged pair", _ray_placer(merged_pair_fill, "known", "mirror")),
)


def _left(a: int, placed: NDArray) -> list[tuple[int, int]]:
    """The runs of fields from ``a`` that ``placed`` leaves."""
    lo, hi = true_runs(~placed)
    return [(a + x, a + y) for x, y in zip(lo.tolist(), hi.tolist(), strict=True)]


def _note(gap: _Gap, made: int) -> None:
    """The expected error of the fills of ``gap.out`` from ``made`` on into
    ``gap.errors`` (read only where a fill's fields are in ``gap.dense``)."""
    for _, fill in gap.out[made:] if gap.errors is not None else ():
        gap.errors[fill.track, fill.first_field : fill.first_field + fill.n_fields] = (
            fill.expected_error_mm
        )


def _apply(
    gap: _Gap, fills: tuple[Fill, ...], runs: list[tuple[int, int]], split: bool = False
) -> None:
    """Try ``fills[0]`` on each run of ``runs`` in its reach, the rest of ``fills`` on
    what it leaves (after all runs when it sweeps, run by run otherwise)."""
    if not fills or not runs:
        return
    head, tail = fills[0], fills[1:]
    left: list[tuple[int, int]] = []
    for a, b in runs:
        if not head.reaches(gap, a, b, split):
            got = [(a, b)]
            placed = False
        else:
            made = len(gap.out)
            mask = head.fill(gap, a, b, head.params_for(gap))
            _note(gap, made)
            got, placed = _left(a, mask), bool(mask.any())
            if head.sweep:
                gap.swept[a - gap.lo : b - gap.lo] |= mask
        if head.sweep:
            left.extend(got)
        else:
            _apply(gap, tail, got, placed or split)
    if head.sweep:
        _apply(gap, tail, left)


def _fill_runs(
    dense: NDArray,
    runs: Iterable[tuple[int, int, int, int]],
    params: TrackingParams,
    spare: SpareBlobs | None,
    measured: NDArray,
    absent: NDArray | None,
    errors: NDArray | None = None,
    mirror: NDArray | None = None,
) -> list[tuple[NDArray, GapFill]]:
    """Each run (track, lo, hi, end) filled by :data:`FILLS` in turn; placed fields become
    context (in ``dense``) for the rest. ``measured``: every track's measured fields;
    ``end``, ``absent`` and ``errors``: see :class:`_Gap`."""
    out = []
    for t, lo, hi, end in runs:
        gap = _Gap(dense, t, lo, hi, params, spare, measured[t], np.zeros(hi - lo, bool), [])
        gap.end, gap.absent, gap.errors, gap.mirror = end, absent, errors, mirror
        _apply(gap, FILLS, [(lo, hi)])
        out += gap.out
    return out


def _second_pass(
    dense: NDArray,
    gaps: list[tuple[int, int, int]],
    params: TrackingParams,
    spare: SpareBlobs | None,
    measured: NDArray,
    made: Iterable[tuple[NDArray, GapFill]],
    absent: NDArray | None = None,
    fills: tuple[Fill, ...] = SECOND_PASS,
    errors: NDArray | None = None,
    mirror: NDArray | None = None,
) -> list[tuple[NDArray, GapFill]]:
    """The fields of ``gaps`` (track, lo, hi) the first pass left (its fills ``made``,
    (xyz, fill) pairs), filled again by ``fills`` (:data:`SECOND_PASS`, or after the
    ends :data:`LAST_PASS`, then :data:`TRUSTED_PASS`), with its rigid and ray fills
    expecting at most ``ray_rest_max_error_mm`` (:func:`~.fill_trusted.context`) written
    into ``dense`` as context (for these fills and the track ends after them).

    Tracks are filled one after another, so a marker's gap is filled before its
    segment's partner's gap in the same fields is: a toe seen by one camera while the
    heel, seen by another one, waits its turn has no partner to be placed by. Once the
    heel is placed, its length holds the toe on its ray as a measured heel's would.
    Spline and pattern fills are not context (one through a partner's wrong samples
    would carry the marker onto them; on rays, the trusted pass's), nor does the body
    expect over ``ray_rest_max_error_mm`` here (with the new context: 12 mm off expecting 4).
    """
    if spare is None:
        return []
    done = np.isfinite(dense[:, :, 0])
    expected = np.where(measured, 0.0, np.nan)
    for xyz, fill in made:
        span = slice(fill.first_field, fill.first_field + fill.n_fields)
        done[fill.track, span] = True
        if context(fill, params, fills is TRUSTED_PASS):
            dense[fill.track, span] = xyz
            expected[fill.track, span] = fill.expected_error_mm
    out = []
    for t, lo, hi in gaps:
        left = ~done[t, lo:hi]
        for a, b in zip(*true_runs(left), strict=True):
            run = (lo + a, lo + b)
            gap = _Gap(dense, t, *run, params, spare, measured[t], np.zeros(b - a, bool), [])
            gap.absent, gap.known, gap.expected = absent, measured, expected
            gap.errors, gap.mirror = errors, mirror
            _apply(gap, fills, [run])
            out.extend(gap.out)
    return out


def fill_gaps_logged(
    tracks: Tracks,
    params: TrackingParams,
    spare: SpareBlobs | None = None,
    labels: Sequence[str] | None = None,
    unlabelled: Sequence[int] = (),
    missing: Sequence[str] = (),
) -> tuple[Tracks, tuple[GapFill, ...]]:
    """Fill the gaps inside each track (fields between its first and last measured sample
    without one, or with only a Kalman prediction under ``refill_predicted``): short ones
    (``max_fill_gap_fields``) by a spline, longer ones (``max_body_fill_fields``) from the
    body (see module); filled samples' ``corrected_mm`` is NaN. Returns the tracks and how
    each gap was filled (method and expected error).

    With ``spare`` (2D blobs no 3D point used), filled fields a camera still sees are moved
    onto its ray (:mod:`kisscal.tracking.rayfill`; a blob fills one sample at most).
    With ``labels`` (one per track), the ends of each named track (not in
    ``unlabelled``) too, once every gap is filled
    (:func:`~kisscal.tracking.fill_ends.track_ends`). ``missing``: the set's names no
    track took, placed on their blobs' rays (:func:`.fill_absent.absent_placed`) for the
    joint fills, and those placed in ``min_track_length`` fields or more as tracks
    numbered after the given ones (:func:`fill_gaps_named` says which names).

    References
    ----------
    Gløersen & Federolf 2016 (filling from the other markers of the body).
    """
    tracks, fills, _ = fill_gaps_named(tracks, params, spare, labels, unlabelled, missing)
    return tracks, fills


def fill_gaps_named(
    tracks: Tracks,
    params: TrackingParams,
    spare: SpareBlobs | None = None,
    labels: Sequence[str] | None = None,
    unlabelled: Sequence[int] = (),
    missing: Sequence[str] = (),
) -> tuple[Tracks, tuple[GapFill, ...], tuple[str, ...]]:
    """:func:`fill_gaps_logged`, with the names of ``missing`` that became tracks (in
    the order of their numbers, after the given tracks')."""
    if tracks.field.size == 0:
        return tracks, (), ()
    start, stop = tracks.bounds()
    meas = tracks.status == MEASURED
    n_fields = int(tracks.field.max()) + 1
    dense = np.full((tracks.n_tracks, n_fields, 3), np.nan)
    dense[tracks.track[meas], tracks.field[meas]] = tracks.xyz_mm[meas]
    measured = np.isfinite(dense[:, :, 0])
    if spare is not None:  # and the blobs of points no named track holds
        who = np.isin(tracks.track, list(unlabelled)) & meas & (tracks.point >= 0)
        spare = freed(spare, tracks.point[who], tracks.track[who], tracks.point[meas])
    again = who, absent, absent_sd = absent_rows(dense, labels, missing, spare, params)
    gaps = [
        (t, lo, hi)
        for t in range(tracks.n_tracks)
        for lo, hi in _track_gaps(tracks, slice(start[t], stop[t]), params)
    ]
    errors = np.concatenate([np.where(measured, 0.0, np.nan), absent_sd])  # placed rows too
    # the placed rows' mirrors too: a chain fill's partner may be one (s50 review)
    names = None if labels is None else [*labels[: tracks.n_tracks], *(w[0] for w in who)]
    mirror = mirror_tracks(names, tracks.n_tracks + len(who))
    first = [(*g, 0) for g in gaps]
    made = _fill_runs(dense, first, params, spare, measured, absent, errors, mirror)
    made += _second_pass(
        dense, gaps, params, spare, measured, made, absent, errors=errors, mirror=mirror
    )
    ends = track_ends(tracks, params, labels, unlabelled)
    made += _fill_runs(dense, ends, params, spare, measured, absent, errors, mirror)
    for last in (LAST_PASS, TRUSTED_PASS):  # the ends placed: a knee carries a tibia
        made += _second_pass(
            dense, gaps, params, spare, measured, made, absent, last, errors, mirror
        )
    named, placed = absent_named(dense, measured, made, labels, again, missing, spare, params)
    made += placed
    filled_xyz, fills = [m[0] for m in made], [m[1] for m in made]
    if not fills:
        return tracks.with_track(tracks.track), (), ()
    new_field = np.concatenate([g.first_field + np.arange(g.n_fields) for g in fills])
    new_track = np.concatenate([np.full(g.n_fields, g.track) for g in fills])
    new_status = np.concatenate([np.full(g.n_fields, g.status, dtype=np.int8) for g in fills])
    # A filled sample replaces the track's sample there (a Kalman prediction).
    replaced = np.zeros((tracks.n_tracks + len(named)) * n_fields, dtype=bool)
    replaced[new_track * n_fields + new_field] = True
    keep = ~replaced[tracks.track * n_fields + tracks.field]
    n = new_field.size
    columns = (
        np.concatenate([tracks.field[keep], new_field]),
        np.concatenate([tracks.track[keep], new_track]),
        np.concatenate([tracks.xyz_mm[keep], *filled_xyz]),
        np.concatenate([tracks.corrected_mm[keep], np.full((n, 3), np.nan)]),
        np.concatenate([tracks.status[keep], new_status]),
        np.concatenate([tracks.point[keep], np.full(n, -1)]),
    )
    # sorted by (track, field), numbers kept: a filled end moves a track's first field,
    # and its name (labels are per track number) must stay with it
    order = np.lexsort((columns[0], columns[1]))
    out = Tracks(*(c[order] for c in columns))
    return out, tuple(fills), tuple(named)
