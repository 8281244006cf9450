"""Phase 4: groups of unnamed pieces that entered the view together are named jointly.

Pieces of one segment that appear together (a whole foot at the edge of the volume)
have no named partner to go by one at a time; their distances to each other and to the
named markers, taken together, pick their names.
"""

from __future__ import annotations

import itertools
import warnings

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from kisscal.tracking.labelling.learned import MAX_SCORE, distance_statistics, trial_scores
from kisscal.tracking.labelling.spread import spread
from kisscal.tracking.labelling.state import MIN_SHARED_FIELDS, RIGID_SPREAD_MM, LabelState
from kisscal.tracking.rigid import kabsch

# Largest number of joint name choices tried for a group of unnamed pieces.
MAX_GROUP_CHOICES = 20000

Piece = tuple[NDArray[np.int64], NDArray[np.float64]]


def unnamed_groups(state: LabelState, split: bool = False) -> list[NDArray[np.int64]]:
    """Groups of 2 to 4 unnamed pieces of at least ``min_body_fit_points`` points, each
    sharing at least three fields with another of its group, in order of their first
    piece; with ``split``, the sub-groups (:func:`_rigid_split`) of the larger ones, of
    any size (their lengths bound the names, :func:`name_group`'s ``links``)."""
    cand = np.flatnonzero(
        (state.label_of < 0) & (state.n_measured >= state.params.min_body_fit_points)
    )
    if cand.size < 2:
        return []
    counts = state.stop[cand] - state.start[cand]
    rows = np.repeat(np.arange(cand.size), counts)
    cols = np.concatenate([state.piece(int(t))[0] for t in cand])
    seen = csr_matrix((np.ones(rows.size), (rows, cols)), shape=(cand.size, state.n_fields))
    shared = (seen @ seen.T).toarray()
    _, component = connected_components(csr_matrix(shared >= 3), directed=False)
    groups = [cand[component == c] for c in np.unique(component)]
    if split:
        groups = [s for g in groups if g.size > 4 for s in _rigid_split(state, g)]
    groups.sort(key=lambda g: int(g[0]))
    return [g for g in groups if 2 <= g.size and (split or g.size <= 4)]


def _rigid_split(state: LabelState, group: NDArray[np.int64]) -> list[NDArray[np.int64]]:
    """The sub-groups of ``group`` joined by pairs of pieces that could be a rigid pair of
    the set: their distance varies by less than ``RIGID_SPREAD_MM`` (SD, over at least
    ``MIN_SHARED_FIELDS`` shared fields) and is, within ``label_segment_tolerance_mm``,
    the template length of some rigid pair.

    Unnamed pieces of several segments seen at one time chain into one group too large
    to name (kiss 3-camera seed 361: a heel and a toe from field 0 with shank and sacrum
    pieces in their fields); the pieces of one segment still keep its lengths.
    """
    link = rigid_links(state, [state.piece(int(t)) for t in group])
    _, component = connected_components(csr_matrix(link), directed=False)
    return [group[component == c] for c in np.unique(component)]


def rigid_links(state: LabelState, pieces: list[Piece]) -> NDArray[np.bool_]:
    """Which two ``pieces`` could be a rigid pair of the set (:func:`_rigid_split`)."""
    lengths = state.template_distance[state.rigid_pairs()]
    k = len(pieces)
    link = np.zeros((k, k), dtype=bool)
    for a, b in itertools.combinations(range(k), 2):
        (fa, xa), (fb, xb) = pieces[a], pieces[b]
        _, ia, ib = np.intersect1d(fa, fb, return_indices=True)
        if ia.size >= MIN_SHARED_FIELDS:
            d = np.linalg.norm(xa[ia] - xb[ib], axis=1)
            off = np.min(np.abs(lengths - np.median(d)), initial=np.inf)
            link[a, b] = np.std(d) < RIGID_SPREAD_MM
            link[a, b] &= off <= state.params.label_segment_tolerance_mm
    return link | link.T


def _between(pieces: list[Piece]) -> NDArray[np.float64]:
    """Median distance between every two pieces over their shared fields (NaN with
    fewer than three)."""
    k = len(pieces)
    between = np.full((k, k), np.nan)
    for a, b in itertools.combinations(range(k), 2):
        (fa, xa), (fb, xb) = pieces[a], pieces[b]
        shared, ia, ib = np.intersect1d(fa, fb, return_indices=True)
        if shared.size >= 3:
            between[a, b] = between[b, a] = np.median(np.linalg.norm(xa[ia] - xb[ib], axis=1))
    return between


def _to_named(pieces: list[Piece], name_pos: NDArray) -> list[NDArray[np.float64]]:
    """Median distance of each piece from every name over its fields (NaN if unseen)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # names never seen with a piece
        return [
            np.nanmedian(np.linalg.norm(name_pos[:, f] - x[None], axis=2), axis=1)
            for f, x in pieces
        ]


def _name_options(
    state: LabelState, pieces: list[Piece], to_named: list[NDArray], rigid: NDArray
) -> list[list[int]]:
    """Per piece, the free names whose named rigid partners in view agree with it."""
    tolerance = state.params.label_segment_tolerance_mm
    options = []
    for (f, _), dist in zip(pieces, to_named, strict=True):
        free = np.flatnonzero(~np.isfinite(state.name_pos[:, f, 0]).any(axis=1))
        keep = []
        for j in free.tolist():
            partners = np.flatnonzero(rigid[j] & np.isfinite(dist))
            miss = dist[partners] - state.template_distance[j, partners]
            if partners.size == 0 or np.sqrt(np.mean(miss**2)) <= tolerance:
                keep.append(j)
        options.append(keep)
    return options


def _choice_rms(
    choice: tuple[int, ...],
    between: NDArray,
    to_named: list[NDArray],
    rigid: NDArray,
    template_distance: NDArray,
) -> float | None:
    """RMS template-length misfit of the rigid pairs a choice of names makes (among the
    pieces and to named partners); None when a piece takes part in no rigid pair."""
    k = len(choice)
    residuals = []
    involved = np.zeros(k, dtype=bool)
    for a in range(k):
        for b in range(a + 1, k):
            if rigid[choice[a], choice[b]] and np.isfinite(between[a, b]):
                residuals.append(between[a, b] - template_distance[choice[a], choice[b]])
                involved[[a, b]] = True
        partners = np.flatnonzero(rigid[choice[a]] & np.isfinite(to_named[a]))
        for q in partners:
            residuals.append(to_named[a][q] - template_distance[choice[a], q])
            involved[a] = True
    if not involved.all():
        return None
    return float(np.sqrt(np.mean(np.square(residuals))))


def _pair_samples(
    pieces: list[Piece], name_pos: NDArray, template: NDArray, reach: float
) -> list[tuple[int, int, NDArray]]:
    """Per two pieces, the vectors joining them turned into the template's frame by the
    body's orientation, in up to five of their shared fields where that orientation's
    rigid fit to the names held is best and within ``reach`` (RMS, mm).

    Legs alone fit the standing template 40-200 mm RMS off as they stride, and the worse
    the fit, the more it turns the body about the vertical (up to 50 degrees; correlation
    0.9 over a synthetic walk): an ASIS pair seen with the sacrum then reads as its
    mirror image (modern 3 cameras seed 424, 99 identity switches).
    """
    out = []
    orientation: dict[int, tuple[float, NDArray] | None] = {}  # per field, shared by pairs
    for a, b in itertools.combinations(range(len(pieces)), 2):
        (fa, xa), (fb, xb) = pieces[a], pieces[b]
        shared, ia, ib = np.intersect1d(fa, fb, return_indices=True)
        fits, seen = [], []
        for f, i, j in zip(shared.tolist(), ia, ib, strict=True):
            if f not in orientation:
                orientation[f] = _body_orientation(name_pos[:, f], template)
            if orientation[f] is None:
                continue
            fit, r = orientation[f]
            fits.append(fit)
            seen.append(r @ (xa[i] - xb[j]))
        best = np.argsort(fits, kind="stable")[:5]
        best = best[np.asarray(fits)[best] <= reach]
        if best.size:
            out.append((a, b, np.asarray(seen)[best]))
    return out


def _body_orientation(pos: NDArray, template: NDArray) -> tuple[float, NDArray] | None:
    """(RMS mm, rotation) of the rigid fit of the names held in one field's ``pos``
    (names, 3) to ``template``; None with fewer than three held."""
    held = np.flatnonzero(np.isfinite(pos[:, 0]))
    if held.size < 3:
        return None
    r, t = kabsch(pos[held], template[held])
    miss = pos[held] @ r.T + t - template[held]
    return float(np.sqrt(np.sum(miss**2) / held.size)), r


def _direction_misfit(
    choice: tuple[int, ...], samples: list[tuple[int, int, NDArray]], template: NDArray
) -> float:
    """Median distance between the vectors joining the pieces in the body's frame
    (:func:`_pair_samples`) and the template's vectors between the chosen names.

    A heel and a toe swapped point the wrong way whatever the joints do.
    """
    d = [
        np.linalg.norm(v - (template[choice[a]] - template[choice[b]]), axis=1)
        for a, b, v in samples
    ]
    return float(np.median(np.concatenate(d))) if d else np.inf


def _settle_rivals(
    state: LabelState, pieces: list[Piece], best: tuple[int, ...], rivals: list[tuple]
) -> tuple[int, ...] | None:
    """Among the best choice and its rivals (only its mirror image, or the same names in
    another order, may rival it), the one the body's rigid fit clearly prefers and
    places within ``label_tolerance_mm`` (:func:`_direction_misfit`)."""
    same = {frozenset(best)}
    if state.mirror_of is not None:
        same.add(frozenset(state.mirror_of[list(best)].tolist()))
    if any(frozenset(c) not in same for c in rivals):
        return None
    options = [best, *rivals]
    reach = state.params.label_tolerance_mm
    samples = _pair_samples(pieces, state.name_pos, state.template, reach)
    fits = [_direction_misfit(c, samples, state.template) for c in options]
    order = np.argsort(fits)
    # the best must also fit (walk.c3d: two trunk pieces 230 mm off T10-CLAV either way)
    if not (fits[order[1]] > 1.5 * fits[order[0]] and fits[order[0]] <= reach):
        return None
    return options[order[0]]


def _fits_links(choice: tuple[int, ...], links: NDArray, apart: NDArray, rigid: NDArray) -> bool:
    c = np.asarray(choice)
    same = c[:, None] == c[None, :]
    np.fill_diagonal(same, False)
    return bool(apart[same].all() and rigid[np.ix_(c, c)][links].all())


def name_group(
    state: LabelState, pieces: list[Piece], rigid: NDArray, links: NDArray | None = None
) -> NDArray[np.int64] | None:
    """Names for a group of unnamed pieces, chosen jointly by their rigid distances.

    Every one-to-one choice of free names is scored by the RMS difference between the
    template lengths and the distances of the pairs it makes rigid: among the pieces, and
    from each piece to named partners. Every piece must take part in at least one rigid
    pair, the best choice must fit within ``label_segment_tolerance_mm`` and be at least
    twice better than any choice that differs in more than a left/right mirror; between a
    choice and its mirror image the rigid fit of the body decides. Returns None when the
    group cannot be named safely.

    With ``links`` (pieces that keep a rigid length of the set, :func:`rigid_links`),
    each linked pair must be named as a rigid pair, and pieces sharing no field may take
    one name (a marker's pieces either side of a gap): kiss 3-camera seed 368's right
    toe kept its heel's and ankle's lengths through two heel pieces, and choices that
    left its 152 mm to the ankle unexplained rivalled the right one.
    """
    between = _between(pieces)
    to_named = _to_named(pieces, state.name_pos)
    options = _name_options(state, pieces, to_named, rigid)
    if np.prod([len(o) for o in options], dtype=float) > MAX_GROUP_CHOICES:
        return None
    scored = []
    if links is not None:
        apart = np.array([[np.intersect1d(a, b).size == 0 for b, _ in pieces] for a, _ in pieces])
    for choice in itertools.product(*options):
        if links is None and len(set(choice)) < len(pieces):
            continue
        if links is not None and not _fits_links(choice, links, apart, rigid):
            continue
        rms = _choice_rms(choice, between, to_named, rigid, state.template_distance)
        if rms is not None:
            scored.append((rms, choice))
    if not scored:
        return None
    scored.sort()
    best_rms, best = scored[0]
    if best_rms > state.params.label_segment_tolerance_mm:
        return None
    rivals = [c for r, c in scored[1:] if r < 2.0 * max(best_rms, 1.0)]
    if rivals:
        best = _settle_rivals(state, pieces, best, rivals)
        if best is None:
            return None
    return np.asarray(best, dtype=np.int64)


def name_groups(state: LabelState) -> None:
    """Phase 4: name every group of unnamed pieces that can be named safely, spreading
    names after each; then the rigid sub-groups of groups too large to name, each piece
    keeping its name's distances as the trial shows them (:func:`.learned.trial_scores`):
    one length alone fits many pairs of a set (a lower-limb file's RTIB and an extra
    shank-cluster marker, 108.5 mm apart, took the head's LFHD-RFHD), and the trial's
    distances tell a foot from a head. When two or more keep them, those are named and
    spreading names the rest from them (kiss 3-camera seed 368: a shank's pieces misfit
    the distances their names showed over 11 fields of another stride phase)."""
    rigid = state.rigid_pairs()
    for group in unnamed_groups(state):
        names_for = name_group(state, [state.piece(int(t)) for t in group], rigid)
        if names_for is not None:
            for t, j in zip(group, names_for, strict=True):
                state.name_piece(int(t), int(j))
            spread(state)
    for group in unnamed_groups(state, split=True):
        if np.any(state.label_of[group] >= 0):
            continue  # named as names spread from an earlier group
        pieces = [state.piece(int(t)) for t in group]
        names_for = name_group(state, pieces, rigid, rigid_links(state, pieces))
        if names_for is None:
            continue
        median, spreads = distance_statistics(state.name_pos)
        scores = [trial_scores(state, int(t), np.array([j]), median, spreads)[0]
                  for t, j in zip(group, names_for, strict=True)]  # fmt: skip
        kept = np.asarray(scores) <= MAX_SCORE**2
        if kept.sum() >= 2:
            for t, j in zip(group[kept], names_for[kept], strict=True):
                state.name_piece(int(t), int(j))
            spread(state)
