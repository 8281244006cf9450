"""Unnamed pieces that fill a named trajectory's gap join it.

With three or four cameras a marker is often measured by two cameras only while its
segment's other markers are hidden too, so spreading (:mod:`.spread`) has no rigid
partner to name the piece by, and it is left ``M<k>`` while its marker's trajectory has
a gap exactly where the piece is, or has ended (modern 3 cameras seed 419: SACR seen
by one camera for 22 fields, then by two and three to the walk's end). Such a piece
joins the named trajectory when it lies inside one of its gaps or past one of its ends
(no field measured by both), continues its path at each end beside it (within ``30 mm``
per field crossed, 150 mm at most, beyond a partner's own motion or the trajectory's own
velocity beside the gap, as :mod:`kisscal.tracking.raychain` follows a path) and keeps
the trajectory's lengths to its segment's partners where they are seen (RMS difference at most
``label_segment_tolerance_mm``, over at least :data:`MIN_LENGTH_CHECKS` of them), and
when exactly one named trajectory is so continued and none is measured where the piece
is (within :data:`SAME_MARKER_MM`: the same marker seen twice). Where fewer than
:data:`MIN_LENGTH_CHECKS` lengths can be checked (kiss 3 cameras seed 418: the right heel
seen by two cameras at the walk's end, ankle and toe by one), those there must hold and the
path alone names the piece: its start within a quarter of the trajectory's distance to its
nearest other marker (:data:`PATH_ONLY_FRACTION`) of the trajectory's end moved across the
gap at their two velocities' mean (:func:`bridge_mm`), unless a name its lengths confirm,
or a pair below, takes the piece or the name. Two pieces past the ends of two segment
partners, neither partner measured there, join them when their distance keeps the
partners' length and one continues its name's path (:func:`_end_pairs`).

References
----------
Shafiq et al. 2001 (joining track pieces of one marker).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.result import Labelling
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.segment_lengths import length_partners
from kisscal.tracking.tracks import MEASURED, make_tracks, numbering

#: Fewest (partner, field) lengths a piece must keep to join a trajectory.
MIN_LENGTH_CHECKS = 3

#: Largest step (mm per field crossed, and in all) from a trajectory's end beside a gap
#: to a piece, beyond its segment partner's own motion.
REACH_MM_PER_FIELD = 30.0
MAX_REACH_MM = 150.0

#: Largest part of a trajectory's distance to its nearest other marker that a piece named
#: by its path alone (no lengths to check) may miss the path by: a neighbour's path is a
#: whole distance off, and a wrong point between them (two blobs merged) half of it.
PATH_ONLY_FRACTION = 0.25

#: A piece nearer than this (mm, on average) to another trajectory where both are measured
#: is that marker seen twice, and joins no gap.
SAME_MARKER_MM = 20.0


def reach_miss(
    track: NDArray, partners: NDArray, x: int, y: int, at_y: NDArray, still: bool = False
) -> float:
    """How far (mm) a piece at ``at_y`` in field ``y`` lies from ``track`` (F, 3), whose
    nearest sample is in field ``x``, moved on to ``y``: as a segment partner
    (``partners``, (k, F, 3)) moved from ``x`` to ``y``, or at the track's own velocity
    beside ``x``, or (with ``still``, or when no partner is seen at both) standing still,
    whichever it lies nearest."""
    n, back = abs(y - x), (-1 if y > x else 1)
    # the step, less the partners' own or the trajectory's own motion at the gap (a
    # foot in swing moves fast, its marker with it)
    own = partners[:, y] - partners[:, x]
    own = own[np.all(np.isfinite(own), axis=1)]
    motion = np.r_[own, np.zeros((int(still or own.size == 0), 3))]
    if 0 <= x + back < track.shape[0]:
        motion = np.r_[motion, (track[x] - track[x + back])[None] * n]
    motion = motion[np.all(np.isfinite(motion), axis=1)]
    step = np.linalg.norm(at_y - track[x] - motion, axis=1)
    return float(step.min())


def reach_limit(x: int, y: int) -> float:
    """The largest :func:`reach_miss` (mm) that continues a trajectory from field ``x``
    to ``y``: :data:`REACH_MM_PER_FIELD` per field crossed, :data:`MAX_REACH_MM` at most."""
    return min(REACH_MM_PER_FIELD * abs(y - x), MAX_REACH_MM)


def reaches(
    track: NDArray, partners: NDArray, x: int, y: int, at_y: NDArray, still: bool = False
) -> bool:
    """Whether a piece at ``at_y`` in field ``y`` continues ``track`` (F, 3), whose
    nearest sample is in field ``x``: within :func:`reach_limit` of that sample moved on
    (:func:`reach_miss`): a partner that moved says the segment did."""
    return reach_miss(track, partners, x, y, at_y, still) <= reach_limit(x, y)


def step_from(seen: NDArray, first: int, last: int) -> list[tuple[int, int]]:
    """Where a piece over fields ``first`` to ``last`` steps from on a trajectory seen
    where ``seen`` (F,) is True: ``(x, first)`` with ``x`` the trajectory's last field
    before the piece, and ``(x, last)`` with ``x`` its first field after, for each side
    that has one (both sides of a gap, or one past an end)."""
    before = np.flatnonzero(seen[:first])[-1:]
    after = last + 1 + np.flatnonzero(seen[last + 1 :])[:1]
    return [(int(x), first) for x in before] + [(int(x), last) for x in after]


def _fits(dense: NDArray, t: int, u: int, params: TrackingParams) -> int:
    """Whether piece ``u`` fills a gap of track ``t``, or continues it past an end (see
    module): 2 by its path and lengths, 1 by its path alone (too few lengths to check),
    0 not."""
    mine, piece = np.isfinite(dense[t, :, 0]), np.flatnonzero(np.isfinite(dense[u, :, 0]))
    a, b = piece[0], piece[-1]
    if mine[a : b + 1].any() or not mine.any():
        return 0
    partners, _ = length_partners(dense, t, params)
    partners = partners[partners != u]
    sides = step_from(mine, a, b)
    for x, y in sides:
        if not reaches(dense[t], dense[partners], x, y, dense[u, y], still=True):
            return 0
    own = np.linalg.norm(dense[partners] - dense[t][None], axis=2)
    length = np.nanmedian(np.where(np.isfinite(own), own, np.nan), axis=1)
    there = np.linalg.norm(dense[partners][:, piece] - dense[u, piece][None], axis=2)
    miss = there - length[:, None]
    miss = miss[np.isfinite(miss)]
    if miss.size and float(np.sqrt(np.mean(miss**2))) > params.label_segment_tolerance_mm:
        return 0
    if miss.size >= MIN_LENGTH_CHECKS:
        return 2
    # too few lengths to check (the segment's partners hidden, or seen by one camera,
    # where the piece is): the path alone names it, when the piece's start meets the
    # trajectory's end moved at their two velocities' mean (a neighbour's path is
    # offset by its distance whatever the body does, standing still is not enough:
    # a body moving 5 mm a field brings a neighbour to the end's place) within a part
    # of the trajectory's distance to its nearest other marker
    near = np.linalg.norm(np.delete(dense, [t, u], axis=0) - dense[t][None], axis=2)
    most = PATH_ONLY_FRACTION * float(np.nanmin(near, initial=np.inf))
    return int(
        bool(np.isfinite(most))
        and all(bridge_mm(dense[t], dense[u], x, y) <= most for x, y in sides)
    )


def bridge_mm(track: NDArray, piece: NDArray, x: int, y: int) -> float:
    """How far (mm) ``piece`` (F, 3) in field ``y`` is from ``track``'s (F, 3) sample in
    field ``x`` moved across the gap at the mean of the two velocities beside it (each
    from its next field away from the gap; NaN when either has none)."""
    s = 1 if y > x else -1
    if not (0 <= x - s < track.shape[0] and 0 <= y + s < piece.shape[0]):
        return float("nan")
    mean_velocity = s * (track[x] - track[x - s] + piece[y + s] - piece[y]) / 2.0
    return float(np.linalg.norm(piece[y] - track[x] - (y - x) * mean_velocity))


def _beside(seen: NDArray, a: int, b: int) -> int | None:
    """The field of ``seen``'s measured sample nearest outside ``[a, b]``, if only one
    side has one (the piece is past the trajectory's end or before its start)."""
    before, after = np.flatnonzero(seen[:a]), b + 1 + np.flatnonzero(seen[b + 1 :])
    if (before.size > 0) == (after.size > 0):
        return None
    return int(before[-1]) if before.size else int(after[0])


def _end_pairs(dense: NDArray, named: list, unnamed: list, params: TrackingParams) -> list:
    """Two unnamed pieces past the ends of two named segment partners (lowcost seed 373:
    RTIB and RANK seen by two cameras only after the rest of the leg left): ``(u, v, t,
    s)`` where ``u`` continues ``t``'s path (:func:`reaches`), ``u``-``v`` keeps ``t``-``s``'s
    length (RMS within ``label_segment_tolerance_mm`` over at least
    :data:`MIN_LENGTH_CHECKS` fields), neither ``t`` nor ``s`` is measured from the
    pieces' first field to their last, and no other pair of names fits the pieces; of
    the two ways round, the one nearer the names' samples beside the pieces."""
    seen = np.isfinite(dense[:, :, 0])
    found: dict = {}
    partners_of: dict = {}
    for u in unnamed:
        for v in unnamed:
            both = seen[u] & seen[v]
            if u == v or both.sum() < MIN_LENGTH_CHECKS:
                continue
            a, b = np.flatnonzero(seen[u] | seen[v])[[0, -1]]
            d = np.linalg.norm(dense[u, both] - dense[v, both], axis=1)
            for t in named:
                x = _beside(seen[t], a, b)
                if x is None:
                    continue
                if t not in partners_of:
                    partners_of[t] = length_partners(dense, t, params)[0]
                partners = partners_of[t]
                for s in partners[np.isin(partners, named)]:
                    z = _beside(seen[s], a, b)
                    if z is None or seen[s, a : b + 1].any():
                        continue
                    length = np.nanmedian(np.linalg.norm(dense[t] - dense[s], axis=1))
                    y, w = (np.flatnonzero(seen[k])[[0, -1]][int(x > b)] for k in (u, v))
                    if float(np.sqrt(np.mean((d - length) ** 2))) > (
                        params.label_segment_tolerance_mm
                    ) or not reaches(
                        dense[t],
                        dense[partners[partners != s]],
                        x,
                        y,
                        dense[u, y][None],
                        still=True,
                    ):
                        continue
                    step = np.linalg.norm(dense[u, y] - dense[t, x]) + np.linalg.norm(
                        dense[v, w] - dense[s, z]
                    )
                    key = (min(u, v), max(u, v))
                    found.setdefault(key, {}).setdefault(frozenset((t, int(s))), []).append(
                        (step, u, v, t, int(s))
                    )
    pairs = [min(next(iter(f.values()))) for f in found.values() if len(f) == 1]
    # a piece or a name in two fitting pairs is ambiguous: none of them
    used = np.bincount(np.ravel([p[1:] for p in pairs]).astype(int), minlength=len(dense))
    return [p[1:] for p in pairs if np.all(used[list(p[1:])] == 1)]


def join_gap_pieces(labelling: Labelling, params: TrackingParams) -> Labelling:
    """``labelling`` with each unnamed piece that fills exactly one named trajectory's
    gap or continues it past an end, and each pair past two partners' ends (see module),
    joined to it; the coasted samples it replaces are dropped and the remaining unnamed
    tracks renamed ``M1``, ``M2``, ... in order."""
    if not labelling.unlabelled or not labelling.fits_marker_set:
        return labelling
    tr = labelling.tracks
    meas = tr.status == MEASURED
    dense = np.full((tr.n_tracks, int(tr.field.max()) + 1, 3), np.nan)
    dense[tr.track[meas], tr.field[meas]] = tr.xyz_mm[meas]
    named = [t for t in range(tr.n_tracks) if t not in set(labelling.unlabelled)]
    into, free, by_path = np.arange(tr.n_tracks), [], {}
    with np.errstate(invalid="ignore"):
        for u in labelling.unlabelled:
            near = np.linalg.norm(dense[named] - dense[u][None], axis=2)
            both = np.isfinite(near)
            mean = np.where(both, near, 0.0).sum(axis=1) / np.maximum(both.sum(axis=1), 1)
            if np.any(both.any(axis=1) & (mean < SAME_MARKER_MM)):
                continue
            free.append(u)
            fit = np.array([_fits(dense, t, u, params) for t in named], dtype=int)
            hosts = np.flatnonzero(fit == 2)
            if hosts.size == 1:
                into[u] = named[int(hosts[0])]
            elif hosts.size == 0 and np.sum(fit == 1) == 1:
                by_path[u] = named[int(np.argmax(fit))]
        pairs = _end_pairs(dense, named, free, params)
        for u, v, t, s in pairs:
            if into[u] == u and into[v] == v:
                into[u], into[v] = t, s
        # a name its path alone gives last: a pair's lengths (modern 3 cameras seed 437:
        # RTOE's piece and RHEE's past their ends) or a piece's own say more
        paired = {int(k) for p in pairs for k in p}
        for u, t in by_path.items():
            if into[u] == u and t not in paired and u not in paired:
                into[u] = t
    if np.all(into == np.arange(tr.n_tracks)):
        return labelling
    # the hosts' coasted samples where a joined piece was measured go
    taken = np.zeros(dense.shape[:2], dtype=bool)
    moved = into[tr.track] != tr.track
    taken[into[tr.track[moved]], tr.field[moved]] = True
    keep = moved | meas | ~taken[tr.track, tr.field]
    cols = [getattr(tr, c)[keep] for c in ("field", "track", "xyz_mm", "corrected_mm")]
    cols[1] = into[cols[1]]
    joined = make_tracks(*cols, tr.status[keep], tr.point[keep])
    ids, rank, _ = numbering(cols[0], cols[1])
    order = np.empty(ids.size, dtype=np.int64)
    order[rank] = ids
    labels, unlabelled = [], []
    for i, old in enumerate(order.tolist()):
        if old in set(labelling.unlabelled):
            unlabelled.append(i)
            labels.append(f"M{len(unlabelled)}")
        else:
            labels.append(labelling.labels[old])
    return dataclasses.replace(
        labelling, tracks=joined, labels=tuple(labels), unlabelled=tuple(unlabelled)
    )
