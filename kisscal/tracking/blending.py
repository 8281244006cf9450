"""Blending of track pieces and clean-up of short tracks (Shafiq et al. 2001 §4.3).

Pieces that end and start within a few fields are joined where Shafiq's extrapolations
and one cubic through both sides say they are one path (:func:`blend_pairs`); the
clean-up then removes tracks with too few measured points: most ghost tracks are short.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from kisscal.tracking.blending_chains import (
    bridge_residual_mm,
    chain_costs,
    extrapolate_gap,
    gap_fields,
    in_fields,
    join_ends,
    ranges,
    through_gaps,
)
from kisscal.tracking.continuity import smoothness_mm
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import MEASURED, Tracks

_FAR = 1e12


def _end_points(
    tracks: Tracks, from_end: bool, depth: int = 5
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Per track: field of the last (first) measured sample, its last (first) up to
    ``depth`` measured positions (nearest last), how many there are, and their fields."""
    n = tracks.n_tracks
    m = np.flatnonzero(tracks.status == MEASURED)
    tr = tracks.track[m]
    start = np.searchsorted(tr, np.arange(n), "left")
    stop = np.searchsorted(tr, np.arange(n), "right")
    count = np.minimum(stop - start, depth)
    history = np.zeros((n, depth, 3))
    fields = np.zeros((n, depth), dtype=np.int64)
    for j in range(depth):
        # j-th point counted from the piece's end (or start), placed nearest-last.
        ok = count > j
        rows = (stop - 1 - j) if from_end else (start + j)
        history[ok, depth - 1 - j] = tracks.xyz_mm[m[rows[ok]]]
        fields[ok, depth - 1 - j] = tracks.field[m[rows[ok]]]
    edge = tracks.field[m[np.where(from_end, stop - 1, start)]] if n else np.empty(0, int)
    return edge, history, count, fields


def _rival_in_gap(
    tracks: Tracks, a: NDArray, b: NDArray, share: float, ends: tuple[NDArray, ...]
) -> NDArray[np.bool_]:
    """Which joins ``a[i]`` -> ``b[i]`` another marker contests inside their gap (``ends``
    as :func:`~kisscal.tracking.blending_chains.chain_costs`).

    At each field of the gap, both sides are extrapolated into it (Shafiq's rule, as the
    coarse gate). A measured sample of a third piece within ``share`` (``blend_rival_share``) of the
    distance between the two extrapolations of the later piece's is the later marker seen
    there; when that third piece began before the earlier piece ended, it ran beside it:
    it is another marker than the earlier one, and the later piece continues it, not the
    earlier one. Likewise a sample on the earlier piece's extrapolation whose piece goes on
    past the later one's start carries the earlier marker on. Fast markers close together
    (a racing glove: 6 m/s, 43 mm apart) pass every continuity test with a neighbour's
    path; the samples in the gap tell them apart.
    """
    out = np.zeros(a.size, dtype=bool)
    end_field, start_field = ends[0], ends[4]
    pair, gap_field, _, fa, fb = gap_fields(a, b, ends)
    if pair.size == 0:
        return out
    ia, ib = a[pair], b[pair]
    q, rows = in_fields(tracks, np.flatnonzero(tracks.status == MEASURED), gap_field)
    x, c = tracks.xyz_mm[rows], tracks.track[rows]
    reach = share * np.linalg.norm(fa[q] - fb[q], axis=1)
    other = (c != ia[q]) & (c != ib[q])
    later_seen = (np.linalg.norm(x - fb[q], axis=1) <= reach) & (start_field[c] <= end_field[ia[q]])
    earlier_seen = (np.linalg.norm(x - fa[q], axis=1) <= reach) & (
        end_field[c] >= start_field[ib[q]]
    )
    out[pair[q[other & (later_seen | earlier_seen)]]] = True
    return out


def _nearer_at_ends(
    tracks: Tracks, a: NDArray, b: NDArray, forward: NDArray, backward: NDArray
) -> tuple[NDArray[np.bool_], NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]]:
    """Which joins ``a[i]`` -> ``b[i]`` another piece's sample explains better at their
    ends: in the later piece's first field, a sample of a third piece lies nearer the
    earlier piece's extrapolation (``forward``) than the later piece's first sample; or,
    in the earlier piece's last field, one lies nearer the later piece's backward
    extrapolation (``backward``) than the earlier piece's last sample. The earlier marker
    is then seen where the join would put it on another piece: a guess, refused (markers
    5 mm apart at 3 m/s, Phoenix LEDs on a golf club, fit one cubic either way).

    A third piece that is itself a rival candidate (``a[i]`` may join it, or it may join
    ``b[i]``) does not refuse the join here: it is returned as a contest (join index,
    rival piece, whether it rivals the later piece) for :func:`_settle_contests` to judge
    once every rival's join is chosen. Judged one join at a time, the sample nearer one
    extrapolation wins: two PhaseSpace markers 30 mm apart, both lost for two fields, lost
    both true joins (each 0.6-10 mm farther than a rival's sample) and kept the crossed
    one alone. A rival's join whose other end misses farther than this join's does not
    contest it: the two ends disagree, and the extrapolations decide nothing (a heel and
    ankle 108 mm apart at 30 Hz, lost for four fields at heel strike: the heel's forward
    guess lay 54 mm from the ankle, 85 from the heel, the heel's backward guess 45 mm from
    the heel, the ankle's 93).

    Returns
    -------
    refused : (n,) bool array
    join, rival : (k,) int arrays
    later : (k,) bool array
    """
    m = np.flatnonzero(tracks.status == MEASURED)
    start_field, start_hist = _end_points(tracks, from_end=False)[:2]
    end_field, end_hist = _end_points(tracks, from_end=True)[:2]
    n = np.int64(tracks.n_tracks)
    key = a * n + b
    order = np.argsort(key)
    miss = {
        True: np.linalg.norm(start_hist[b, -1] - forward, axis=1),
        False: np.linalg.norm(end_hist[a, -1] - backward, axis=1),
    }
    out = np.zeros(a.size, dtype=bool)
    joins, rivals, sides = [], [], []
    for at, guess, later in ((start_field[b], forward, True), (end_field[a], backward, False)):
        q, rows = in_fields(tracks, m, at)
        c = tracks.track[rows]
        d = np.linalg.norm(tracks.xyz_mm[rows] - guess[q], axis=1)
        mine = b[q] if later else a[q]
        theirs = a[q] * n + c if later else c * n + b[q]
        at_key = order[np.minimum(np.searchsorted(key[order], theirs), a.size - 1)]
        rival = key[at_key] == theirs
        # the rival join's other end must agree (miss no farther than this join's there)
        agree = ~rival | (miss[not later][at_key] <= miss[not later][q])
        better = (c != mine) & (d < miss[later][q]) & agree
        out[q[better & ~rival]] = True
        joins.append(q[better & rival])
        rivals.append(c[better & rival])
        sides.append(np.full(joins[-1].size, later))
    return out, np.concatenate(joins), np.concatenate(rivals), np.concatenate(sides)


def _unresolved_ends(
    tracks: Tracks,
    a: NDArray,
    b: NDArray,
    guesses: tuple[NDArray, NDArray],
    ends: tuple[NDArray, ...],
    floor_mm: float,
) -> NDArray[np.bool_]:
    """Which joins ``a[i]`` -> ``b[i]`` neither extrapolation resolves: at both ends, the
    extrapolation across the gap (``guesses``: forward into the later piece's first field,
    backward into the earlier piece's last) misses the other piece's sample there by more
    than ``floor_mm`` (the continuity tolerance: a miss within the noise says nothing of
    the motion) and by more than that sample lies from another piece's sample.

    A prediction tells two samples apart only when its error is smaller than their
    spacing; beyond it, which one it meets nearer is chance, and a cubic through both
    pieces fits either (Phoenix LEDs 18 mm apart on a golf club moving 130 mm a field,
    lost for one field: the extrapolations missed the other LED's piece by 28 and 23 mm,
    the LED's own samples lay 31 and 41 mm from them). Such a join is a guess at both
    ends: refused, the gap left (``ends`` as
    :func:`~kisscal.tracking.blending_chains.chain_costs`).
    """
    m = np.flatnonzero(tracks.status == MEASURED)
    out = np.ones(a.size, dtype=bool)
    for at, guess, own, mine in (
        (ends[4][b], guesses[0], ends[5][b, -1], b),
        (ends[0][a], guesses[1], ends[1][a, -1], a),
    ):
        miss = np.linalg.norm(own - guess, axis=1)
        q, rows = in_fields(tracks, m, at)
        spacing = np.linalg.norm(tracks.xyz_mm[rows] - own[q], axis=1)
        close = np.zeros(a.size, dtype=bool)
        close[q[(tracks.track[rows] != mine[q]) & (spacing < miss[q])]] = True
        out &= close & (miss > floor_mm)
    return out


def _settle_contests(
    n_tracks: int,
    a: NDArray,
    b: NDArray,
    join: NDArray,
    rival: NDArray,
    later: NDArray,
) -> NDArray[np.bool_]:
    """Which chosen joins ``a[i]`` -> ``b[i]`` keep: a join whose end a rival candidate's
    sample explained better (:func:`_nearer_at_ends`; ``join`` indexes the chosen pairs)
    stands only when the assignment gave that rival to another piece. The rival's sample
    is then another marker's, accounted for; a rival left without a partner may be this
    marker seen on another piece, and the join a guess."""
    partner_of_later = np.full(n_tracks, -1, dtype=np.int64)
    partner_of_later[b] = a
    partner_of_earlier = np.full(n_tracks, -1, dtype=np.int64)
    partner_of_earlier[a] = b
    partner = np.where(later, partner_of_later[rival], partner_of_earlier[rival])
    own = np.where(later, a[join], b[join])
    keep = np.ones(a.size, dtype=bool)
    keep[join[(partner < 0) | (partner == own)]] = False
    return keep


def blend_pairs(
    tracks: Tracks, params: TrackingParams, noise_mm: float | None = None
) -> tuple[NDArray, NDArray]:
    """Pairs (earlier piece, later piece) that blending connects.

    A later piece must start 1 .. ``blend_gap_fields + 1`` fields after the earlier one
    ends. Shafiq's extrapolations from both sides across the gap must land within
    ``blend_reach_mm`` per field crossed of the other piece (a coarse gate), and one cubic
    through the last and first ``blend_points`` measured points of the two pieces must
    fit them within ``max(blend_tolerance_mm, blend_noise_factor * noise_mm)`` RMS (the
    continuity test: extrapolations of a fast foot over a few fields miss by centimetres,
    a wrong join leaves a jump no smooth curve absorbs); a join must be as smooth as its
    pieces (:func:`_smooth_as_pieces`) and no other marker seen in its gap may contest it
    (:func:`_rival_in_gap`). Pairs are then chosen one-to-one by that residual, rival
    joins together (:func:`_choose`): a rival candidate's sample nearer a join's ends does
    not refuse it alone (:func:`_nearer_at_ends`), the choice of every rival's join
    settles it. A join with a rival candidate across a gap where one-sample pieces lie in
    reach is judged (cost and tolerance) by the path through them, and takes them in
    (:func:`~kisscal.tracking.blending_chains.chain_costs`). ``noise_mm`` defaults to
    :func:`~kisscal.tracking.continuity.smoothness_mm` of the tracks.
    """
    if tracks.n_tracks < 2:
        e = np.empty(0, dtype=np.int64)
        return e, e
    end_field, end_hist, end_n, end_fields = _end_points(tracks, from_end=True)
    start_field, start_hist, start_n, start_fields = _end_points(tracks, from_end=False)
    ends = (end_field, end_hist, end_n, end_fields, start_field, start_hist, start_n, start_fields)
    # Only pieces that became Kalman tracks take part: shorter ones are initial tracks
    # that died, mostly ghosts, and a few points can line up with anything.
    grown = np.flatnonzero(tracks.n_status(MEASURED) >= params.min_initial_length)
    by_start = grown[np.argsort(start_field[grown], kind="stable")]
    starts_sorted = start_field[by_start]
    lo = np.searchsorted(starts_sorted, end_field[grown] + 1, "left")
    hi = np.searchsorted(starts_sorted, end_field[grown] + params.blend_gap_fields + 2, "left")
    a = np.repeat(grown, hi - lo)
    b = by_start[ranges(lo, hi)]
    if a.size == 0:
        e = np.empty(0, dtype=np.int64)
        return e, e
    ahead = start_field[b] - end_field[a]
    forward = extrapolate_gap(end_hist[a], end_n[a], ahead)
    backward = extrapolate_gap(start_hist[b], start_n[b], ahead)
    miss_f = np.linalg.norm(forward - start_hist[b, -1], axis=1)
    miss_b = np.linalg.norm(backward - end_hist[a, -1], axis=1)
    reach = params.blend_reach_mm * ahead
    near = (miss_f <= reach) & (miss_b <= reach)
    a, b = a[near], b[near]
    refused, contest, rival, later = _nearer_at_ends(tracks, a, b, forward[near], backward[near])
    if noise_mm is None:
        noise_mm = smoothness_mm(tracks)
    tolerance = max(params.blend_tolerance_mm, params.blend_noise_factor * noise_mm)
    refused |= _unresolved_ends(tracks, a, b, (forward[near], backward[near]), ends, tolerance)
    k = params.blend_points
    residual = np.array(
        [bridge_residual_mm(*join_ends(ends, i, j, k)) for i, j in zip(a, b, strict=True)]
    )
    ok = (residual <= tolerance) & ~refused if residual.size else np.zeros(0, bool)
    floor = max(noise_mm, tolerance / params.blend_rougher)
    smooth = _smooth_as_pieces(tracks, a[ok], b[ok], floor, params)
    ok[ok] = smooth & ~_rival_in_gap(tracks, a[ok], b[ok], params.blend_rival_share, ends)
    # A join with a rival in the coarse gate, across a gap where the markers were seen as
    # one-sample pieces, is judged by the path through those samples, not end to end
    # (blending_chains). Without a rival it stays judged end to end: the tracker cut a
    # lone marker there for a stray sample (pc_real: 1.5 mm end to end, 5.3 through it).
    judged = np.flatnonzero(ok & _rivalled(a, b))
    chain, routes = chain_costs(tracks, a[judged], b[judged], ends, k, params.blend_reach_mm)
    seen = judged[np.isfinite(chain)]
    residual[seen] = chain[np.isfinite(chain)]
    ok[seen] = residual[seen] <= tolerance
    cost = np.where(ok, residual, _FAR)
    earlier, later = _choose(tracks.n_tracks, a, b, cost, (contest, rival, later))
    paths = dict(zip(zip(a[judged].tolist(), b[judged].tolist(), strict=True), routes, strict=True))
    return through_gaps(earlier, later, paths)


def _rivalled(a: NDArray, b: NDArray) -> NDArray[np.bool_]:
    """Which candidate joins ``a[i]`` -> ``b[i]`` share a piece with another."""
    _, ia, na = np.unique(a, return_inverse=True, return_counts=True)
    _, ib, nb = np.unique(b, return_inverse=True, return_counts=True)
    return (na[ia.ravel()] > 1) | (nb[ib.ravel()] > 1)


def _choose(
    n_tracks: int, a: NDArray, b: NDArray, cost: NDArray, contests: tuple[NDArray, ...]
) -> tuple[NDArray, NDArray]:
    """The joins chosen one-to-one at least total ``cost`` (:func:`_assign`) whose
    contests the choice settles (:func:`_settle_contests`); a join left unsettled is
    withdrawn and the rest chosen again, so that its rivals may take the pieces."""
    contest, rival, later = contests
    cost = cost.copy()
    while True:
        chosen = _assign(a, b, cost)
        index = np.full(a.size, -1, dtype=np.int64)
        index[chosen] = np.arange(chosen.size)
        mine = index[contest] >= 0
        keep = _settle_contests(
            n_tracks, a[chosen], b[chosen], index[contest[mine]], rival[mine], later[mine]
        )
        if keep.all():
            return a[chosen], b[chosen]
        cost[chosen[~keep]] = _FAR


def _assign(a: NDArray, b: NDArray, cost: NDArray) -> NDArray[np.int64]:
    """Indices of the pairs ``a[i]`` -> ``b[i]`` chosen one-to-one at least total ``cost``
    (``_FAR``: not allowed)."""
    allowed = np.flatnonzero(cost < _FAR)
    if allowed.size == 0:
        return allowed
    ra, ia = np.unique(a[allowed], return_inverse=True)
    cb, ib = np.unique(b[allowed], return_inverse=True)
    matrix = np.full((ra.size, cb.size), _FAR)
    matrix[ia, ib] = cost[allowed]
    pair = np.full((ra.size, cb.size), -1, dtype=np.int64)
    pair[ia, ib] = allowed
    r, c = linear_sum_assignment(matrix)
    return np.sort(pair[r, c][matrix[r, c] < _FAR])


def _smooth_as_pieces(
    tracks: Tracks, a: NDArray, b: NDArray, floor_mm: float, params: TrackingParams
) -> NDArray:
    """Which joins ``a[i]`` -> ``b[i]`` are as smooth as the pieces themselves: one cubic
    through the last and first ``blend_join_points`` measured samples of the two fits them
    within ``blend_rougher`` times the RMS residual of a cubic through the last (first)
    ``blend_piece_points`` samples of either piece (at least ``floor_mm``)."""
    if a.size == 0:
        return np.zeros(0, dtype=bool)
    k, rougher = params.blend_join_points, params.blend_rougher
    _, end_hist, end_n, end_fields = _end_points(tracks, True, params.blend_piece_points)
    _, start_hist, start_n, start_fields = _end_points(tracks, False, params.blend_piece_points)
    out = np.ones(a.size, dtype=bool)
    for n, (i, j) in enumerate(zip(a, b, strict=True)):
        fa, xa = end_fields[i, -end_n[i] :], end_hist[i, -end_n[i] :]
        fb, xb = start_fields[j, -start_n[j] :][::-1], start_hist[j, -start_n[j] :][::-1]
        join = bridge_residual_mm(fa[-k:], xa[-k:], fb[:k], xb[:k])
        own = [bridge_residual_mm(f[:0], x[:0], f, x) for f, x in ((fa, xa), (fb, xb))]
        own = max([floor_mm, *(r for r in own if np.isfinite(r))])
        out[n] = join <= rougher * own
    return out


def chain_labels(n_tracks: int, earlier: NDArray, later: NDArray) -> NDArray[np.int64]:
    """Group number per track after joining each ``earlier[i]`` to ``later[i]``."""
    nxt = np.full(n_tracks, -1, dtype=np.int64)
    nxt[earlier] = later
    has_prev = np.zeros(n_tracks, dtype=bool)
    has_prev[later] = True
    group = np.full(n_tracks, -1, dtype=np.int64)
    for g, head in enumerate(np.flatnonzero(~has_prev)):
        t = head
        while t >= 0:
            group[t] = g
            t = nxt[t]
    return group


def blend_tracks(tracks: Tracks, params: TrackingParams, noise_mm: float | None = None) -> Tracks:
    """Connect track pieces whose gap and continuity allow it (Shafiq et al. 2001 §4.3);
    the missing fields of a blended gap are left empty for gap filling."""
    earlier, later = blend_pairs(tracks, params, noise_mm)
    if earlier.size == 0:
        return tracks
    return tracks.with_track(chain_labels(tracks.n_tracks, earlier, later)[tracks.track])


def clean_up(tracks: Tracks, params: TrackingParams) -> Tracks:
    """Remove tracks with fewer than ``min_track_length`` measured samples (ghost tracks)."""
    n_measured = tracks.n_status(MEASURED)
    return tracks.select(n_measured[tracks.track] >= params.min_track_length)
