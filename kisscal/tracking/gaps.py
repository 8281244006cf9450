"""Gap filling of final trajectories (smoothing is :mod:`kisscal.tracking.smooth`'s).

Gaps inside a trajectory (blended gaps, and coasted fields whose Kalman prediction is
replaced by a two-sided estimate) are filled by a cubic interpolating spline through the
measured samples on both sides when short, and from the body (rigid-body or pattern fill,
:mod:`kisscal.tracking.bodyfill`; about two markers' axis, :mod:`kisscal.tracking.fill_hinge`)
when longer, and on the rays of blobs a camera still sees
(:data:`~kisscal.tracking.fill_passes.FILLS` gives the order,
:mod:`kisscal.tracking.fill_runner` runs them).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kisscal._shared import true_runs
from kisscal.tracking.bodyfill import GapFill
from kisscal.tracking.fill_absent import absent_rows, mirror_tracks
from kisscal.tracking.fill_absent_again import AbsentContext, absent_named
from kisscal.tracking.fill_ends import track_ends
from kisscal.tracking.fill_passes import FILLS, LAST_PASS, SECOND_PASS
from kisscal.tracking.fill_runner import fill_runs, second_pass
from kisscal.tracking.fill_trusted import TRUSTED_PASS
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs, freed
from kisscal.tracking.tracks import MEASURED, PREDICTED, Tracks, is_filled


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
    made = fill_runs(dense, first, params, spare, measured, absent, FILLS, errors, mirror)
    made += second_pass(
        dense, gaps, params, spare, measured, made, absent, SECOND_PASS, errors, mirror
    )
    ends = track_ends(tracks, params, labels, unlabelled)
    made += fill_runs(dense, ends, params, spare, measured, absent, FILLS, errors, mirror)
    for last, trusting in ((LAST_PASS, False), (TRUSTED_PASS, True)):  # the ends placed:
        made += second_pass(  # a knee carries a tibia
            dense, gaps, params, spare, measured, made, absent, last, errors, mirror, trusting
        )
    ctx = AbsentContext(dense, measured, made, labels, again, missing, spare, params)
    named, placed = absent_named(ctx)
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
