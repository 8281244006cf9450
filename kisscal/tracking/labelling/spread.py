"""Phases 2 and 3: names spread from the named pieces to the others, and windows where
unnamed long pieces remain are matched again.

A name is free for a piece if no trajectory holds it in the piece's fields; among the
free names the piece takes the one whose rigid partners (markers on the same body
segment) stay at the template's distance from it, or, failing a clear answer, the one
whose expected position seen from the named markers around it the piece keeps to;
with no rigid partner in view, a name whose trajectory the piece does not continue
gives way to the one name whose trajectory it does, seen from the segment and the next
(:func:`~.paths.by_segment_path`). Naming one piece gives its neighbours a partner, so
this repeats.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.blending import bridge_residual_mm
from kisscal.tracking.labelling.facing import facing
from kisscal.tracking.labelling.learned import MAX_SCORE, distance_statistics, trial_scores
from kisscal.tracking.labelling.paths import by_segment_path
from kisscal.tracking.labelling.pelvis import across_walk_name, mirror_side_name
from kisscal.tracking.labelling.pieces import reaches, step_from
from kisscal.tracking.labelling.state import CLEAR_RATIO, LONE_NAME_REACH, LabelState
from kisscal.tracking.labelling.window import match_window
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rigid import kabsch

# Passes over the unnamed pieces; each pass only retries pieces near newly named ones.
MAX_SWEEPS = 200
# Windows matched to the template after the first, where unnamed long pieces remain.
MAX_WINDOWS = 12
#: A shorter window of phase 3 names pieces only when its fit RMS to the template is at
#: most this many times the first window's (held-out trials: 1.1 where it named a leg
#: right, 3 to 4 where pieces mixing two markers of a foot took names).
SHORT_WINDOW_FIT = 1.5
#: A long piece takes the one name a rigid partner confirms, other names having no
#: partner in view, when they are seen together this many times ``min_track_length``.
HELD_PIECES = 3
#: A body-fit name is declined when another candidate keeps the distances the trial
#: showed at least this much better (mean squared spreads, :mod:`.learned`; over k names
#: held around, a likelihood ratio of exp(k / 2) against the body fit's name).
TRIAL_VETO = 1.0


def by_segments(
    piece_fields: NDArray,
    piece_xyz: NDArray,
    free: NDArray,
    name_pos: NDArray,
    rigid: NDArray,
    template_distance: NDArray,
    params: TrackingParams,
) -> tuple[int, NDArray[np.int64], NDArray[np.int64]]:
    """Free name whose rigid partners keep their template distance from a piece.

    Partners are the name pairs known to be rigid: given segments, or found rigid among
    the trajectories named from the average pose.

    Returns the name pinned by two or more partners (-1 if none), the free names that one
    partner allows, and those without any partner in view.
    """
    # Called thousands of times on pieces of a few fields (ghosts), so written for few
    # numpy calls: the norm as np.linalg.norm computes it, and NaN (a name not held in a
    # field) left in the residual where the weight drops it anyway.
    diff = name_pos[:, piece_fields] - piece_xyz[None]
    d = np.sqrt(np.add.reduce(diff * diff, axis=2))  # (n, F)
    seen = np.isfinite(d)
    partners = rigid[free]  # (J, n)
    used = partners & seen.any(axis=1)
    # Short pieces are mostly ghosts: ask them for a closer fit.
    short = piece_fields.size < params.min_track_length
    tolerance = params.label_segment_tolerance_mm * (0.5 if short else 1.0)
    residual2 = (d[None, :, :] - template_distance[free][:, :, None]) ** 2
    weight = used[:, :, None] & seen[None, :, :]
    count = weight.sum(axis=(1, 2))
    rms = np.sqrt(np.where(weight, residual2, 0.0).sum(axis=(1, 2)) / np.maximum(count, 1))
    n_used = used.sum(axis=1)
    fits = (n_used > 0) & (rms <= tolerance)
    # One partner leaves the piece anywhere on a sphere around it, which a ghost near the
    # body may touch by chance; two pin it to a circle, enough for a piece that moves
    # along it for a few fields; a point or two needs three when the name has three.
    n_partners = partners.sum(axis=1)
    pinned = fits & (n_used >= np.minimum(3 if piece_fields.size < 3 else 2, n_partners))
    pinned &= n_used >= 2
    best = int(free[np.argmin(np.where(pinned, rms, np.inf))]) if pinned.any() else -1
    return best, free[fits & (n_used == 1)], free[n_used == 0]


def body_fit_distances(
    piece_fields: NDArray, piece_xyz: NDArray, free: NDArray, name_pos: NDArray, template: NDArray
) -> NDArray[np.float64]:
    """Distance of the piece from where each free name is expected, at up to 9 fields
    (rows; NaN where fewer than three names are held).

    The body's orientation R comes from a rigid fit of every named marker to the
    template; name j is expected at P_k + R^T (T_j - T_k) from each of its four
    template-nearest named neighbours k (local, so that bent joints far away do not
    matter).
    """
    pick = np.linspace(0, piece_fields.size - 1, min(9, piece_fields.size)).round().astype(int)
    dist = np.full((pick.size, free.size), np.nan)
    for i, row in enumerate(pick):
        f = piece_fields[row]
        held = np.flatnonzero(np.isfinite(name_pos[:, f, 0]))
        if held.size < 3:
            continue
        r, _ = kabsch(name_pos[held, f], template[held])
        gap = np.linalg.norm(template[free][:, None] - template[held][None], axis=2)
        near = held[np.argsort(gap, axis=1)[:, :4]]  # (J, 4) nearest named neighbours
        expect = name_pos[near, f] + (template[free][:, None, :] - template[near]) @ r
        dist[i] = np.linalg.norm(piece_xyz[row] - expect.mean(axis=1), axis=1)
    return dist


def by_body_fit(
    piece_fields: NDArray,
    piece_xyz: NDArray,
    free: NDArray,
    name_pos: NDArray,
    template: NDArray,
    params: TrackingParams,
    prefer: NDArray | None = None,
) -> int:
    """Free name whose expected position, seen from its nearest named neighbours, the
    piece keeps closest to, if clearly closer than any other free name (-1 if none).

    The median distance over the fields (:func:`body_fit_distances`) decides; the best
    must be within ``label_tolerance_mm`` and the runner-up
    :data:`~.state.CLEAR_RATIO` times farther.
    A single name in ``prefer`` (confirmed by one rigid partner) is taken when within
    ``label_tolerance_mm`` and no other is :data:`~.state.CLEAR_RATIO` times closer.
    """
    dist = body_fit_distances(piece_fields, piece_xyz, free, name_pos, template)
    # A row is NaN throughout or nowhere: the median of the rows with distances is the
    # NaN-aware median, without np.nanmedian's masked arrays (slow on small ones).
    fitted = ~np.isnan(dist[:, 0])
    if not fitted.any():
        return -1
    score = np.median(dist[fitted], axis=0)
    order = np.argsort(score)
    best = score[order[0]]
    second = score[order[1]] if order.size > 1 else np.inf
    tolerance = params.label_tolerance_mm
    if best <= tolerance and second >= CLEAR_RATIO * best:
        return int(free[order[0]])
    if free.size == 1 and best <= LONE_NAME_REACH * tolerance:
        # The only name the rigid partners leave: the body fit need only roughly agree
        # (the other side's marker of the pair would lie farther still).
        return int(free[0])
    if prefer is not None and prefer.size == 1:
        # The one name a rigid partner confirms wins unless the body clearly disagrees.
        k = int(np.flatnonzero(free == prefer[0])[0])
        others = np.delete(score, k)
        if score[k] <= tolerance and not (others < score[k] / CLEAR_RATIO).any():
            return int(prefer[0])
    return -1


def continues(track_pos: NDArray, fields: NDArray, xyz: NDArray, params: TrackingParams) -> bool:
    """Whether a piece continues a named trajectory smoothly where they are close in time.

    The trajectory's samples up to ``max_fill_gap_fields + 1`` fields before and after
    the piece and the piece itself must fit one polynomial (cubic, or lower with few
    points) within ``split_tolerance_mm`` RMS; with no such samples the piece passes.
    """
    reach = params.max_fill_gap_fields + 1
    near = np.concatenate(
        (np.arange(fields[0] - reach, fields[0]), np.arange(fields[-1] + 1, fields[-1] + reach + 1))
    )
    near = near[(near >= 0) & (near < track_pos.shape[0])]
    near = near[np.isfinite(track_pos[near, 0])]
    if near.size < 2:
        return True
    residual = bridge_residual_mm(near, track_pos[near], fields, xyz)
    return not residual > params.split_tolerance_mm


def _held_through(state: LabelState, fields: NDArray, partners: NDArray) -> bool:
    """Whether the names ``partners`` (mask) are seen together with a piece in at least
    half of its ``fields`` and in :data:`HELD_PIECES` times ``min_track_length`` of them:
    a distance kept that long while the body walks is a segment's, not a chance (nor a
    short piece named wrongly before it)."""
    seen = np.isfinite(state.name_pos[partners][:, fields, 0]).any(axis=0).sum()
    return bool(seen >= max(HELD_PIECES * state.params.min_track_length, fields.size / 2))


def _partner_rms(
    state: LabelState, fields: NDArray, xyz: NDArray, names: NDArray, rigid: NDArray
) -> NDArray[np.float64]:
    """Per name, RMS misfit (mm) of the piece's distances to that name's rigid partners
    held in its fields against the template's."""
    d = np.linalg.norm(state.name_pos[:, fields] - xyz[None], axis=2)  # (n, F)
    out = np.full(names.size, np.inf)
    for i, j in enumerate(names.tolist()):
        miss = d[rigid[j]] - state.template_distance[j, rigid[j]][:, None]
        if np.isfinite(miss).any():
            out[i] = np.sqrt(np.nanmean(miss**2))
    return out


def by_continuity(
    state: LabelState, fields: NDArray, xyz: NDArray, names: NDArray, rigid: NDArray
) -> int:
    """The one of ``names`` (each confirmed by one rigid partner) whose trajectory the
    piece continues where it ends and begins (:func:`~.pieces.reaches`), if the body fit
    too puts the piece nearest that name's expected place; -1 otherwise. An ASIS and
    the sacrum of a pelvis whose sides are alike, once the other ASIS is out of view,
    are told apart by where each was last seen."""
    pos = state.name_pos
    at = {int(fields[0]): xyz[0], int(fields[-1]): xyz[-1]}
    ok = []
    for j in names.tolist():
        ends = step_from(np.isfinite(pos[j, :, 0]), int(fields[0]), int(fields[-1]))
        if ends and all(reaches(pos[j], pos[rigid[j]], x, y, at[y]) for x, y in ends):
            ok.append(j)
    if len(ok) != 1:
        return -1
    dist = body_fit_distances(fields, xyz, names, pos, state.template)
    fitted = ~np.isnan(dist[:, 0])
    if not fitted.any():
        return -1
    return ok[0] if names[np.argmin(np.median(dist[fitted], axis=0))] == ok[0] else -1


def _trial_prefers_other(state: LabelState, t: int, names: NDArray, j: int) -> bool:
    """Whether piece ``t`` keeps the distances the trial showed between another of
    ``names`` and the names held around it better than ``j``'s (by :data:`TRIAL_VETO`;
    phase 5's misfit, :mod:`.learned`), when the trial showed ``j``'s.

    The body fit places a standing template on the named markers around the piece; a
    lone pelvis marker among walking legs is expected 100-180 mm off (lowcost seed 315:
    the right ASIS nearer the sacrum's expected place than its own), while its distances
    to the legs, as the trial showed them while the pelvis was named, tell the names
    apart.
    """
    median, spread_sd = distance_statistics(state.name_pos, names)
    score = trial_scores(state, t, names, median, spread_sd)
    own = score[names == j][0]
    return bool(np.isfinite(own) and np.any(score <= own - TRIAL_VETO))


def _trial_disowns(state: LabelState, t: int, j: int) -> bool:
    """Whether piece ``t`` keeps the distances the trial showed (:mod:`.learned`, within
    ``MAX_SCORE`` spreads) for some free name but not for ``j``, a window's name for it.

    A window's average pose, when its other core pieces are one leg's, places a marker
    of the other foot by template distances that a stride bends (kiss 3-camera seed 368:
    the right toe, 137 fields, took RKNE, a name never seen, and on its true path RANK,
    seen for 11 fields); the trial's distances to the names around tell a foot marker.
    """
    f, _ = state.piece(t)
    free = np.flatnonzero(~np.isfinite(state.name_pos[:, f, 0]).any(axis=1))
    median, spread_sd = distance_statistics(state.name_pos, free)
    kept = trial_scores(state, t, free, median, spread_sd) <= MAX_SCORE**2
    return bool(kept.any() and not kept[free == j].any())


def name_for_piece(state: LabelState, t: int, rigid: NDArray, continuity: bool = False) -> int:
    """The name piece ``t`` takes now (-1: none yet), by its rigid partners, then by
    the body fit (with ``continuity``, then by :func:`by_continuity`); a short piece must
    also continue its name's trajectory."""
    params = state.params
    f_t, xyz_t = state.piece(t)
    free = np.flatnonzero(~np.isfinite(state.name_pos[:, f_t, 0]).any(axis=1))
    if free.size == 0:
        return -1
    j, one_partner, unknown = by_segments(
        f_t, xyz_t, free, state.name_pos, rigid, state.template_distance, params
    )
    undecided = np.concatenate((one_partner, unknown))
    long = state.n_measured[t] >= params.min_track_length
    if j < 0 and one_partner.size == 1 and long:
        # Every other free name is ruled out by its rigid partners, or has none in view,
        # and one partner confirms this one: a long piece (not a ghost) takes it when
        # it is alone or when that partner keeps the template distance through most of
        # the piece (a toe by its heel, while the shank above is never seen).
        if undecided.size == 1 or _held_through(state, f_t, rigid[one_partner[0]]):
            j = int(one_partner[0])
    if j < 0 and undecided.size and state.n_measured[t] >= params.min_body_fit_points:
        j = by_body_fit(
            f_t, xyz_t, undecided, state.name_pos, state.template, params, prefer=one_partner
        )
        if one_partner.size >= 2 and j in one_partner:
            # Names that one partner each confirms (an ASIS and the sacrum by the other
            # ASIS): the body fit, from markers across joints, may only pick the one
            # whose partners keep their distance best.
            rms = _partner_rms(state, f_t, xyz_t, one_partner, rigid)
            if one_partner[np.argmin(rms)] != j:
                j = -1
        if j >= 0 and one_partner.size == 0:
            j = by_segment_path(state, t, undecided, rigid, j)
        if j >= 0:
            j = across_walk_name(state, t, undecided, j)
        if j >= 0 and _trial_prefers_other(state, t, undecided, j):
            j = -1
    if j < 0 and long and one_partner.size == 2 and state.mirror_of is not None:
        a, b = one_partner.tolist()
        # a mirror pair by a partner on the midline, which keeps its distances alike
        if state.mirror_of[a] == b and _held_through(state, f_t, rigid[a] & rigid[b]):
            j = mirror_side_name(state, t, one_partner)
            j = -1 if j >= 0 and _trial_prefers_other(state, t, undecided, j) else j
    if continuity and j < 0 and one_partner.size >= 2 and long:
        # Where the piece continues a name's trajectory and the body fit agrees, the
        # trial's own evidence outweighs the distance statistics' veto.
        j = by_continuity(state, f_t, xyz_t, one_partner, rigid)
    # A short piece next to its name's trajectory must continue it: a ghost by a marker
    # that just went out of sight need not.
    if j >= 0 and not long and not continues(state.name_pos[j], f_t, xyz_t, params):
        j = -1
    return j


def _piece_rows(state: LabelState, pieces: NDArray) -> tuple[NDArray, NDArray, NDArray]:
    """The rows of every piece one after another, where each piece starts among them,
    and how many rows each has."""
    lengths = state.stop[pieces] - state.start[pieces]
    offsets = np.concatenate(([0], np.cumsum(lengths)[:-1]))
    rows = np.repeat(state.start[pieces] - offsets, lengths) + np.arange(lengths.sum())
    return rows, offsets, lengths


def _has_free_name(state: LabelState, pieces: NDArray) -> NDArray[np.bool_]:
    """Whether some name is held in none of each piece's fields (all pieces at once)."""
    if pieces.size == 0:
        return np.zeros(0, dtype=bool)
    rows, offsets, _ = _piece_rows(state, pieces)
    held = np.isfinite(state.name_pos[:, state.tracks.field[rows], 0])
    return ~np.logical_or.reduceat(held, offsets, axis=1).all(axis=0)


def _hopeless(state: LabelState, pieces: NDArray, rigid: NDArray) -> NDArray[np.bool_]:
    """Which of ``pieces`` (too short for the body fit or the one-partner rule) no free
    name fits by two seen rigid partners: :func:`by_segments` would return -1, as long
    as no name is given in their fields. All pieces at once; the RMS, summed in another
    order here, is given a margin of 1e-6, far above the rounding."""
    params = state.params
    rows, offsets, lengths = _piece_rows(state, pieces)
    diff = state.name_pos[:, state.tracks.field[rows]] - state.tracks.xyz_mm[rows]
    d = np.sqrt(np.add.reduce(diff * diff, axis=2))  # (n, S): NaN where a name is not held
    seen = np.isfinite(d)
    seen_in_piece = np.logical_or.reduceat(seen, offsets, axis=1)  # (n, P)
    j, k = np.nonzero(rigid)  # the rigid pairs, by name j
    if j.size == 0:
        return np.ones(pieces.size, dtype=bool)
    residual2 = np.where(seen[k], (d[k] - state.template_distance[j, k][:, None]) ** 2, 0.0)
    # Sums per piece and then per name, as reductions (not BLAS, which may spread over
    # threads for nothing).
    first = np.flatnonzero(np.concatenate(([True], j[1:] != j[:-1])))
    per_piece = np.stack(
        [
            np.add.reduceat(residual2, offsets, axis=1),
            np.add.reduceat(seen[k], offsets, axis=1, dtype=float),
            seen_in_piece[k],
        ]
    )  # (3, pairs, P)
    total, count, n_used = np.add.reduceat(per_piece, first, axis=1)  # (names, P) each
    rms = np.sqrt(total / np.maximum(count, 1.0))
    tolerance = params.label_segment_tolerance_mm * np.where(
        lengths < params.min_track_length, 0.5, 1.0
    )
    could_pin = ~seen_in_piece[j[first]] & (n_used >= 2) & (rms <= tolerance * (1 + 1e-6))
    return ~could_pin.any(axis=0)


def _sweep(state: LabelState, rigid: NDArray, stamp: NDArray, sweep: int, continuity: bool) -> bool:
    """One pass of :func:`spread` over the unnamed pieces, longest first; whether it
    named any."""
    params = state.params
    waiting = np.flatnonzero((state.label_of < 0) & (state.n_measured >= params.min_label_points))
    # Names are only given during a sweep, never taken: a piece without a free name now
    # has none at its turn either, and would take none.
    waiting = waiting[_has_free_name(state, waiting)]
    waiting = waiting[np.argsort(-state.n_measured[waiting], kind="stable")]
    # The short pieces come last, most of them ghosts: once the longer pieces have had
    # their turn, they are screened all at once and only those that could be named by
    # their rigid partners, or around which a name is given after the screening, tried.
    few = min(params.min_body_fit_points, params.min_track_length)
    n_long = int((state.n_measured[waiting] >= few).sum())
    hopeless = np.zeros(waiting.size, dtype=bool)
    touched = np.zeros(state.n_fields, dtype=bool)  # names given after the screening
    changed = False
    for i, t in enumerate(waiting.tolist()):
        if i == n_long:
            hopeless[i:] = _hopeless(state, waiting[i:], rigid)
            touched[:] = False
        f_t = state.tracks.field[state.start[t] : state.stop[t]]
        if sweep > 1 and stamp[f_t].max() < sweep - 1:
            continue  # nothing new around this piece since it was last tried
        if hopeless[i] and not touched[f_t].any():
            continue
        j = name_for_piece(state, t, rigid, continuity)
        if j >= 0:
            state.name_piece(t, j)
            stamp[f_t] = sweep
            touched[f_t] = True
            changed = True
    return changed


def spread(state: LabelState, continuity: bool = False) -> None:
    """Phase 2: other pieces, longest first, take names by their rigid partners, in
    sweeps until a sweep names nothing; a sweep retries only pieces near fields where
    the previous one named something. With ``continuity`` (last, once every other phase
    has named what it could), a long piece that two names' partners allow alike may
    take the one whose trajectory it continues (:func:`by_continuity`)."""
    rigid = state.rigid_pairs()
    stamp = np.zeros(state.n_fields, dtype=np.int64)  # last pass that named something there
    for sweep in range(1, MAX_SWEEPS + 1):
        if not _sweep(state, rigid, stamp, sweep, continuity):
            break
        # Newly named pieces may show more rigid pairs (a name absent from the average
        # pose had none yet).
        rigid = state.rigid_pairs()


def _busiest_unnamed(state: LabelState, tried: NDArray) -> int | None:
    """Centre of the untried window where most unnamed long pieces are seen (None when
    no long piece is unnamed or too few are seen together)."""
    unnamed = state.label_of[state.long_ids] < 0
    busy = np.convolve(state.present[unnamed].sum(axis=0), np.ones(state.window), mode="same")
    busy[tried] = 0
    if not unnamed.any() or busy.max() < 3 * state.window * 0.5:
        return None
    return int(np.argmax(busy))


def rematch(state: LabelState) -> None:
    """Phase 3: windows where unnamed long pieces remain are matched to the template
    again (:func:`~kisscal.tracking.labelling.window.match_window`); a core piece takes
    its name there if the name is free in its fields; names spread after each window.

    Windows of the first match's length first; then, while long pieces stay unnamed,
    windows of half that length and less (down to twice ``label_fields``): with few
    cameras a leg's pieces may each cover half the trial, none of them seen through a
    long window, while the names the first window gave hold the rest. A shorter window
    gives names only when it agrees with every name its core pieces already hold (a
    window that names the pelvis otherwise names the rest wrongly too) and its average
    pose fits the template at most ``SHORT_WINDOW_FIT`` times worse than the first
    window's (a piece that holds two markers in turn bends the pose). A piece that keeps
    a free name's distances as the trial showed them takes no name whose distances it
    does not keep, or that the trial never showed (:func:`_trial_disowns`). A window
    whose match faces backwards (:func:`~kisscal.tracking.labelling.facing.facing`: kiss 3
    cameras seed 434, its first 116 fields named turned round, 10 of 10 names wrong)
    gives none.
    """
    longest = state.window
    length = longest
    try:
        while length >= max(2 * state.params.label_fields, 3):
            state.window = length
            _rematch_windows(state, agree=length < longest)
            if np.all(state.label_of[state.long_ids] >= 0):
                return
            length //= 2
    finally:
        state.window = longest


def _rematch_windows(state: LabelState, agree: bool) -> None:
    """:func:`rematch` at the window length of ``state.window``; with ``agree``, only
    windows whose match keeps the names of the core pieces already named."""
    tried = np.zeros(state.n_fields, dtype=bool)
    for i in range(MAX_WINDOWS):
        if i:
            spread(state)
        centre = _busiest_unnamed(state, tried)
        if centre is None:
            return
        tried[max(centre - state.window // 2, 0) : centre + state.window // 2] = True
        found = match_window(state, centre)
        if found.core is None or (
            # turned round, the body fits as well by distances; the walk tells (facing.py)
            facing(state, found.core, found.assign, found.rich) <= 1 - state.params.facing_fraction
        ):
            continue
        held = state.label_of[state.long_ids[found.core]]
        if agree and (
            np.any((held >= 0) & (held != found.assign))
            or not found.fit_rms <= SHORT_WINDOW_FIT * state.fit_rms
        ):
            continue
        for k, j in zip(found.core, found.assign, strict=True):
            t = state.long_ids[k]
            if j < 0 or state.label_of[t] >= 0:
                continue
            free = not np.isfinite(state.name_pos[j, state.present[k], 0]).any()
            if free and not _trial_disowns(state, int(t), int(j)):
                state.name_piece(int(t), int(j))
