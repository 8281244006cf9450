"""The last contest for each foot's names: distances to the shank and within the foot,
and the walk.

Labelling matches positions to a standing template; a walking foot sits on average 80-130
mm behind where the standing pose puts it, so the match can hand the ankle's name to the
heel's trajectory and the toe's to the ankle's (a real Vicon walk), and a short piece
named from the body's fit (placed from the knee and thigh, off by a step while the foot
rolls) can take its neighbour's name (an ankle piece of seven fields named heel with
three cameras). Two things do not depend on the pose: the distances between a foot's
markers and from them to the shank's (heel to toe is the foot's length, the ankle is the
shank marker's neighbour), and the walk (a subject walks forward, so the toe lies ahead
of the heel and the ankle, and the ankle ahead of the heel, along the direction the body
moves: :mod:`~kisscal.tracking.labelling.footwalk`).

:func:`settle_feet` scores a way of giving a foot's names by one number,
:func:`score`: the mean squared relative error of its distances against the template's,
divided by ``foot_margin`` when it puts two of the foot's markers out of that order
along the walk in ``facing_fraction`` of the fields. Another way replaces the
labelling's own when it scores at most ``foot_margin`` times as much (a name seen with
none of these is judged first by its rigid partner,
:mod:`~kisscal.tracking.labelling.footpartner`): first for the names' whole trajectories
and the unnamed pieces near the shank (with fewer of them than names, as a foot with no
heel marker has, some names are left free), then for each piece
holding a foot name (with the name's holder, or an unnamed piece at the foot's distance,
as its partner: when its distances fit the template either way within
``label_segment_tolerance_mm``, as a heel's and a toe's to the shank alone do, or a
heel's and an ankle's to each other alone, their ratio is noise and the walk decides); last,
unnamed pieces near the foot take a free foot name that scores far better than the
others and fits the foot's rigid distances. It runs after the first window, after the
first spreading (a foot named the wrong way round would give its neighbours' names to
the wrong pieces as names spread) and again after the last naming pass.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from itertools import permutations

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.facing import HEEL, foot_pairs
from kisscal.tracking.labelling.footkeep import continued as _continued
from kisscal.tracking.labelling.footkeep import fit_mm
from kisscal.tracking.labelling.footpartner import (
    MIN_SHARED,
    name_distances,
    settle_lone_foot_names,
)
from kisscal.tracking.labelling.footwalk import ordered_pairs, out_of_order, trailing
from kisscal.tracking.labelling.pelvis import walking_direction
from kisscal.tracking.labelling.spread import continues, spread
from kisscal.tracking.labelling.state import LabelState, median_distances

#: Name endings of the ankle and of the shank markers beside a foot's heel and toe
#: (``<side>HEE`` and ``<side>TOE``, :func:`~kisscal.tracking.labelling.facing.foot_pairs`).
_ANKLE = ("ANK",)
_SHANK = ("KNE", "KNEE", "TIB")
#: A way of giving a foot's names that scores within this factor of the way kept is a
#: near tie: the names the two give differently are doubtful (:func:`_near_ties`).
#: Among foreign foot markers (pyCGM2's metatarsal heads), the ways that put the heel's
#: or the ankle's name on another marker score within 1.11 of the best.
FOOT_TIE = 1.25


@dataclass(frozen=True)
class Foot:
    """Name indices of one foot: the shank's, the foot's (ankle first when the set has
    one), the toe and heel among the foot's (positions in ``names``), and the (front,
    back) pairs of positions in ``names`` whose order along the walk the contest holds to
    (:func:`~kisscal.tracking.labelling.footwalk.ordered_pairs`; the toe and heel alone
    until :func:`settle_feet` reads them from its template)."""

    shank: NDArray[np.int64]
    names: NDArray[np.int64]
    toe: int
    heel: int
    order: tuple[tuple[int, int], ...] = ()


def feet_of(names: tuple[str, ...]) -> list[Foot]:
    """The feet the naming convention gives: ``<side>TOE`` and ``<side>HEE`` (or
    ``HEEL``, ``CAL``), with ``<side>ANK`` and the shank's ``<side>KNE`` and
    ``<side>TIB`` when present."""
    index = {n: i for i, n in enumerate(names)}
    out = []
    for toe, heel in foot_pairs(names):
        side = HEEL.match(names[heel]).group(1)
        ankle = [index[side + a] for a in _ANKLE if side + a in index]
        shank = [index[side + s] for s in _SHANK if side + s in index]
        if shank:
            foot = np.array([*ankle, heel, toe], dtype=np.int64)
            ends = ((len(ankle) + 1, len(ankle)),)  # the toe ahead of the heel
            out.append(Foot(np.array(shank, dtype=np.int64), foot, toe, heel, ends))
    return out


def score(
    dist: NDArray, target: NDArray, trails: NDArray, margin: float, use: NDArray | None = None
) -> NDArray:
    """The contest's score of each way of naming (rows): mean squared relative error of
    its distances ``dist`` against ``target`` (the last axis) over the pairs in ``use``
    (default all: a way that leaves a name free has no distance for it), divided by
    ``margin`` where it ``trails`` (puts two of the foot's markers out of their order
    along the walk); infinite when a pair used was never
    seen together (a piece that fits by seeing little) or none is used."""
    use = np.ones(np.shape(dist), dtype=bool) if use is None else use
    rel = np.where(use, ((dist - target) / target) ** 2, 0.0)
    seen = (np.isfinite(rel) | ~use).all(axis=-1) & use.any(axis=-1)
    total = np.where(np.isfinite(rel), rel, 0.0).sum(axis=-1)
    err = np.where(seen, total / np.maximum(use.sum(axis=-1), 1), np.inf)
    return np.where(trails, err / margin, err)


def naming_choices(n_candidates: int, n_names: int) -> NDArray[np.int64]:
    """Every way (rows) of giving ``n_names`` names to distinct candidates: the candidate
    of each name, -1 for a name left free when there are fewer candidates than names (a
    foot with no heel marker: its heel name is not forced on the ankle)."""
    if n_candidates >= n_names:
        return np.array(list(permutations(range(n_candidates), n_names)), dtype=np.int64)
    slots = list(range(n_candidates)) + [-1] * (n_names - n_candidates)
    return np.array(sorted(set(permutations(slots, n_names))), dtype=np.int64)


def settle_feet(state: LabelState, template: NDArray) -> bool:
    """Give each foot's names (:func:`feet_of`) the way that fits ``template`` and the
    walk far better than the labelling's own, then spread names again; returns whether
    any name moved.

    A piece holding a foot name seen with none of the shank's and the foot's other names
    is first judged by its rigid partner
    (:func:`~kisscal.tracking.labelling.footpartner.settle_lone_foot_names`). Then three
    rounds with one :func:`score`: the foot's names as whole trajectories together with up
    to ``foot_candidates`` unnamed long pieces within ``foot_reach`` of the shank
    (:func:`_name_contest`); each piece holding a foot name against the foot's other names
    in its fields (:func:`_piece_contest`); unnamed pieces near the foot for the foot's
    names free in their fields (:func:`_unnamed_contest`).

    References
    ----------
    Winter 2009 (segment lengths proportional to stature, which a scaled template assumes).
    """
    target = np.linalg.norm(template[:, None] - template[None, :], axis=2)
    direction = walking_direction(state.name_pos)
    moved = False
    for foot in (_seen_shank(state, f) for f in feet_of(state.names)):
        foot = replace(foot, order=ordered_pairs(template, foot.names, foot.toe, foot.heel))
        moved |= settle_lone_foot_names(state, foot.names, foot.shank, foot.order, direction)
        moved |= _name_contest(state, foot, target, direction)
        moved |= _piece_contest(state, foot, target, direction)
        moved |= _unnamed_contest(state, foot, target, direction)
    if moved:
        spread(state)  # a renamed foot gives its ankle a partner
    return moved


def _seen_shank(state: LabelState, foot: Foot) -> Foot:
    """``foot`` with only the shank names held somewhere (all when none is): a distance
    to a name never seen is unknown, yet :func:`score` makes every way using it
    infinite, and a knee never seen left a heel and a toe exchanged."""
    seen = np.isfinite(state.name_pos[foot.shank, :, 0]).any(axis=1)
    return replace(foot, shank=foot.shank[seen]) if seen.any() else foot


def _name_contest(state: LabelState, foot: Foot, target: NDArray, direction: NDArray) -> bool:
    """The foot's names given among their trajectories and the unnamed pieces near the
    shank by the best :func:`score` when it is at most ``foot_margin`` of the held one;
    with fewer of them than names, as many names as there are candidates are given
    (:func:`naming_choices`), the others left free. When the names as held put two
    markers out of their order along the walk (the toe behind the heel, the ankle behind
    the heel), the best way that does not and fits the template within
    ``label_segment_tolerance_mm`` (RMS) is taken whatever the scores' ratio: within
    noise, the walk decides (as in :func:`_piece_better`)."""
    params = state.params
    held_any = np.isfinite(state.name_pos[foot.names, :, 0]).any(axis=1)
    if not held_any.any():
        return False  # no naming of the labelling's own to compare with
    pool = _near_unnamed(state, foot, target)
    cand = np.concatenate([state.name_pos[foot.names[held_any]], state.dense[pool]])
    k, s = foot.names.size, foot.shank.size
    if cand.shape[0] < 2:
        return False  # nothing to give another way
    pos = np.concatenate([state.name_pos[foot.shank], cand])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        d = median_distances(pos, np.arange(pos.shape[0]), np.arange(state.n_fields))
    order = foot.order
    behind = trailing(cand[:, None], cand[None, :], direction, params.facing_fraction)
    names = np.concatenate([foot.shank, foot.names])
    i, j = np.triu_indices(s + k, 1)
    keep = j >= s
    i, j = i[keep], j[keep]
    choices = naming_choices(cand.shape[0], k)
    given = np.where(choices >= 0, s + choices, -1)
    cols = np.concatenate([np.broadcast_to(np.arange(s), (len(choices), s)), given], 1)
    both, trails = out_of_order(choices, behind, order)
    use = (cols[:, i] >= 0) & (cols[:, j] >= 0)
    dist, want = d[cols[:, i], cols[:, j]], target[names[i], names[j]]
    scores = score(dist, want, trails, params.foot_margin, use)
    held = np.where(held_any, np.cumsum(held_any) - 1, -1)
    own, own_trails = _own_score(d, held, s, names, target, behind, order, params.foot_margin)
    # A way that fits within noise in the walk's order beats names out of it.
    forward = both & ~trails & (fit_mm(dist, want, use) <= params.label_segment_tolerance_mm)
    best = int(
        np.argmin(np.where(forward, scores, np.inf) if own_trails and forward.any() else scores)
    )
    if not (own_trails and forward[best]) and (
        not np.isfinite(own) or scores[best] > params.foot_margin * own
    ):
        _near_ties(state, foot, choices, scores, held, own)
        return False
    _near_ties(state, foot, choices, scores, choices[best], scores[best])
    if np.array_equal(choices[best], held):
        return False
    evidence = (d[s:, s:], behind, np.isfinite(cand[..., 0]), target[np.ix_(names[s:], names[s:])])
    tolerance = params.label_segment_tolerance_mm
    kept = _continued(choices[best], np.flatnonzero(held_any), evidence, order, tolerance)
    _rename_names(state, foot, held_any, pool, choices[best], kept)
    return True


def _near_ties(
    state: LabelState, foot: Foot, choices: NDArray, scores: NDArray, kept: NDArray, at: float
) -> None:
    """Doubt (``state.doubtful``) the foot's names that a way of giving them scoring
    within :data:`FOOT_TIE` of the way ``kept`` (score ``at``) gives to another candidate:
    the distances do not tell which marker is the name's (a foot with markers of another
    set: metatarsal heads beside the toe, a malleolus beside the ankle)."""
    if not np.isfinite(at):
        return
    close = choices[scores <= FOOT_TIE * at]
    differ = (close != kept[None, :]).any(axis=0)
    state.doubtful |= {int(j) for j in foot.names[differ]}


def _own_score(d, held, s, names, target, behind, order, margin) -> tuple[float, bool]:
    """:func:`score` of the names as held, over the names held (the shank's always), and
    whether they put a pair of ``order`` (positions) out of order along the walk."""
    given = np.flatnonzero(held >= 0)
    cols = np.concatenate([np.arange(s), s + held[given]])
    sub = np.concatenate([np.arange(s), s + given])
    i, j = np.triu_indices(cols.size, 1)
    keep = j >= s
    i, j = i[keep], j[keep]
    trails = bool(out_of_order(held, behind, order)[1][0])
    return float(
        score(d[cols[i], cols[j]], target[names[sub[i]], names[sub[j]]], trails, margin)
    ), trails


def _near_unnamed(state: LabelState, foot: Foot, target: NDArray) -> NDArray[np.int64]:
    """Rows of ``state.dense`` of unnamed long pieces within ``foot_reach`` times the
    template's farthest foot-to-shank distance of every shank marker (median), the
    ``foot_candidates`` most often seen."""
    params = state.params
    rows = np.flatnonzero(state.label_of[state.long_ids] < 0)
    seen = state.present[rows].sum(axis=1)
    rows = rows[seen > 0]
    if rows.size == 0 or params.foot_candidates == 0:
        return rows
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        d = np.stack(
            [
                np.nanmedian(np.linalg.norm(state.dense[rows] - state.name_pos[j], axis=2), 1)
                for j in foot.shank
            ],
            axis=1,
        )
    reach = params.foot_reach * target[np.ix_(foot.shank, foot.names)].max(axis=1)
    rows = rows[(d <= reach).all(axis=1)]
    order = np.argsort(-state.present[rows].sum(axis=1), kind="stable")
    return rows[order[: params.foot_candidates]]


def _rename_names(
    state: LabelState, foot: Foot, held_any: NDArray, pool: NDArray, choice: NDArray, kept: dict
) -> None:
    """Foot name ``i`` to candidate ``choice[i]``: the pieces of a held name (candidates
    first, in the foot's order) or an unnamed long piece of ``pool``; none for -1; and to
    candidate ``kept[i]`` too when there is one."""
    held_names = foot.names[held_any]
    pieces = [np.flatnonzero(state.label_of == j) for j in held_names]
    pieces += [state.long_ids[[r]] for r in pool]
    for j in foot.names:
        state.label_of[state.label_of == j] = -1
        state.name_pos[j] = np.nan
    for j, c in zip(foot.names, choice, strict=True):
        for t in pieces[c] if c >= 0 else ():
            state.name_piece(int(t), int(j))
    for i, c in kept.items():
        for t in pieces[c]:
            state.name_piece(int(t), int(foot.names[i]))


def _piece_contest(state: LabelState, foot: Foot, target: NDArray, direction: NDArray) -> bool:
    """Each piece holding a foot name, shortest first, against each other foot name in
    its fields: it takes the name, and its partner there takes its own, whose
    :func:`score` of its distances to the shank and the rest of the foot is lowest of
    those at most ``foot_margin`` of its own (the first in the foot's order gave a toe
    piece named ankle, seen with the knee alone, the heel's name though the toe's scored
    better: modern 3 seed 464). The partner is the name's holder in those fields, else an
    unnamed piece at the template's distance between the two names (within
    ``label_segment_tolerance_mm``, median over the fields both are seen), else none."""
    moved = False
    order = np.flatnonzero(np.isin(state.label_of, foot.names))
    for p in order[np.argsort(state.n_measured[order], kind="stable")].tolist():
        n = int(state.label_of[p])
        fields = state.piece(p)[0]
        if n not in foot.names or fields.size < MIN_SHARED:
            continue
        ways = []
        for m in foot.names[foot.names != n].tolist():
            holders = _overlapping(state, np.flatnonzero(state.label_of == m), fields)
            # The name's holders there; where it is free, an unnamed partner or none.
            partners = [holders] if holders else [[u] for u in _partners(state, p, n, m)] + [[]]
            alt = [
                _piece_better(state, foot, p, n, m, _positions(state, q, fields), target, direction)
                for q in partners
            ]
            better = [(a, q) for a, q in zip(alt, partners, strict=True) if a is not None]
            ways += [(better[0][0], m, q) for _, q in better]  # ranked by its first partner
        for _, m, q in sorted(ways, key=lambda w: w[0]):  # stable: partners in order
            if _exchange(state, p, n, m, q):
                moved = True
                break
    return moved


def _overlapping(state: LabelState, pieces: NDArray, fields: NDArray) -> list[int]:
    """The ``pieces`` seen in any of ``fields``."""
    return [int(q) for q in pieces if np.intersect1d(state.piece(int(q))[0], fields).size]


def _positions(state: LabelState, pieces: list[int], fields: NDArray) -> NDArray:
    """Positions of ``pieces`` at ``fields`` (NaN where none is seen)."""
    out = np.full((fields.size, 3), np.nan)
    for q in pieces:
        f_q, x_q = state.piece(q)
        _, i, j = np.intersect1d(fields, f_q, return_indices=True)
        out[i] = x_q[j]
    return out


def _partners(state: LabelState, p: int, n: int, m: int) -> list[int]:
    """Unnamed pieces seen with piece ``p`` in :data:`MIN_SHARED` fields or more at the
    state's template distance between names ``n`` and ``m`` (within
    ``label_segment_tolerance_mm``, median)."""
    fields, xyz = state.piece(p)
    tracks = state.tracks
    rows = np.flatnonzero(np.isin(tracks.field, fields) & (tracks.track != p))
    out = []
    for q in np.unique(tracks.track[rows]).tolist():
        if state.label_of[q] >= 0:
            continue
        other = _positions(state, [q], fields)
        d = np.linalg.norm(other - xyz, axis=1)
        d = d[np.isfinite(d)]
        length = state.template_distance[n, m]
        if d.size >= MIN_SHARED and abs(np.median(d) - length) <= (
            state.params.label_segment_tolerance_mm
        ):
            out.append(q)
    return out


def _piece_better(
    state: LabelState,
    foot: Foot,
    p: int,
    n: int,
    m: int,
    other: NDArray,
    target: NDArray,
    direction: NDArray,
) -> float | None:
    """The :func:`score` of piece ``p`` (named ``n``) named ``m`` with its partner at
    positions ``other`` (its fields) named ``n``, when it is far better than as held;
    None otherwise. When the distances fit the template both ways within
    ``label_segment_tolerance_mm`` (RMS), they cannot tell the names apart and the walk
    alone decides: the exchange is better when the names as held put two of the foot's
    markers out of order along the walk (:func:`_trails_as`) and the exchange does not
    (kiss 3 seed 460: a heel named ankle, the ankle's piece heel)."""
    fields, xyz = state.piece(p)
    refs = np.concatenate([foot.shank, foot.names[(foot.names != n) & (foot.names != m)]])
    pos = np.concatenate([state.name_pos[refs][:, fields], other[None]])
    d = np.linalg.norm(pos - xyz[None], axis=2)
    shared = np.isfinite(d).sum(axis=1) >= MIN_SHARED
    if not shared.any():
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        dist = np.nanmedian(d[shared], axis=1)
    refs_used = np.concatenate([refs, [m]])[shared]
    own_t = target[n, refs_used]
    alt_t = target[m, np.where(refs_used == m, n, refs_used)]  # the pair n-m either way
    fraction, margin = state.params.facing_fraction, state.params.foot_margin
    own_trails = _trails_as(state, foot, fields, {n: xyz, m: other}, direction, fraction)
    alt_trails = _trails_as(state, foot, fields, {m: xyz, n: other}, direction, fraction)
    tolerance = state.params.label_segment_tolerance_mm
    fit = fit_mm(dist, np.stack([own_t, alt_t]), np.ones((2, dist.size), dtype=bool))
    own = float(score(dist, own_t, own_trails, margin))
    alt = float(score(dist, alt_t, alt_trails, margin))
    if fit.max() <= tolerance:
        # Both ways fit within noise (a heel and a toe seen with the shank alone: the
        # tibia and knee are about as far from either, kiss template 264 and 266 mm):
        # the scores' ratio is noise (0.4 against 0.9 mm), the walk decides.
        return alt if own_trails and not alt_trails else None
    return alt if np.isfinite(own) and alt <= margin * own else None


def _trails_as(state, foot, fields, at, direction, fraction) -> bool:
    """Whether a pair of ``foot.order`` is the other way round along the walk in
    ``fields`` with the names ``at`` placed so (other names where the labelling has
    them): the toe trailing the heel or the ankle, the ankle the heel."""
    pos = [at.get(j, state.name_pos[j, fields]) for j in foot.names.tolist()]
    return any(bool(trailing(pos[f], pos[b], direction[fields], fraction)) for f, b in foot.order)


def _exchange(state: LabelState, p: int, n: int, m: int, partners: list[int]) -> bool:
    """Piece ``p`` named ``m`` and its ``partners`` named ``n``, when ``n`` is free in
    the partners' fields but for ``p``; returns whether it did."""
    fields = state.piece(p)[0]
    state.name_pos[n, fields] = np.nan
    for q in partners:
        if np.isfinite(state.name_pos[n, state.piece(q)[0], 0]).any():
            state.name_piece(p, n)
            return False
    for q in partners:
        if state.label_of[q] == m:
            state.name_pos[m, state.piece(q)[0]] = np.nan
    state.name_piece(p, m)
    for q in partners:
        state.name_piece(q, n)
    return True


def _unnamed_contest(state: LabelState, foot: Foot, target: NDArray, direction: NDArray) -> bool:
    """Unnamed pieces near the foot, longest first, take a foot name free in all their
    fields: the one whose :func:`score` (distances to the shank and to the rest of the
    foot) is at most ``foot_margin`` of every other free name's, with no two of the
    foot's markers out of order along the walk (:func:`_trails_as`), when the distances
    within the foot (a rigid segment) fit the state's template within
    ``label_segment_tolerance_mm`` RMS (as spreading names requires: half that for a
    piece shorter than ``min_track_length``, which must also continue the name's
    trajectory)."""
    params = state.params
    cands = _near_pieces(state, foot, target)
    moved = False
    for u in cands[np.argsort(-state.n_measured[cands], kind="stable")].tolist():
        fields, xyz = state.piece(u)
        free = [m for m in foot.names.tolist() if not np.isfinite(state.name_pos[m, fields]).any()]
        # Short pieces are mostly ghosts: as when names spread, a closer fit, and the
        # name's trajectory continued.
        short = state.n_measured[u] < params.min_track_length
        tolerance = params.label_segment_tolerance_mm * (0.5 if short else 1.0)
        scores, fits = [], []
        for m in free:
            refs = np.concatenate([foot.shank, foot.names[foot.names != m]])
            dist = name_distances(state, fields, xyz, refs)
            seen = np.isfinite(dist)
            if not seen.any():
                scores.append(np.inf)
                fits.append(False)
                continue
            trails = _trails_as(state, foot, fields, {m: xyz}, direction, params.facing_fraction)
            scores.append(float(score(dist[seen], target[m, refs[seen]], trails, 1.0)))
            inner = seen & np.isin(refs, foot.names)
            miss = dist[inner] - state.template_distance[m, refs[inner]]
            ok = inner.any() and np.sqrt(np.mean(miss**2)) <= tolerance
            fits.append(bool(ok and np.isfinite(scores[-1]) and not trails))
        if not free:
            continue
        best = int(np.argmin(scores))
        rest = np.delete(np.asarray(scores), best)
        if short and not continues(state.name_pos[free[best]], fields, xyz, params):
            continue
        if fits[best] and (rest.size == 0 or scores[best] <= params.foot_margin * rest.min()):
            state.name_piece(u, free[best])
            moved = True
    return moved


def _near_pieces(state: LabelState, foot: Foot, target: NDArray) -> NDArray[np.int64]:
    """Unnamed pieces of at least :data:`MIN_SHARED` samples whose first sample lies
    within ``foot_reach`` times the template's farthest foot distance of a shank or foot
    name seen there."""
    cands = np.flatnonzero((state.label_of < 0) & (state.n_measured >= MIN_SHARED))
    if cands.size == 0:
        return cands
    refs = np.concatenate([foot.shank, foot.names])
    first = state.start[cands]
    at = state.name_pos[refs][:, state.tracks.field[first]]
    d = np.linalg.norm(at - state.tracks.xyz_mm[first][None], axis=2)
    reach = state.params.foot_reach * target[np.ix_(refs, foot.names)].max(axis=1)
    with np.errstate(invalid="ignore"):
        return cands[(d <= reach[:, None]).any(axis=0)]
