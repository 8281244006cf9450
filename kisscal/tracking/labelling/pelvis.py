"""The pelvis' front and back names, and an ASIS exchanged with the sacrum.

A pelvis named with the sacrum and one ASIS exchanged passes every left/right check: the
sacrum lies on the midline, so whichever ASIS name it holds, it still lies on that
ASIS's side of the other one. Its distances are the template's mirror image at worst,
which a rigid fit to a short or poorly seen window cannot always tell. The walk can: the
anterior superior iliac spines lie ahead of the sacrum (and the posterior spines) along
the direction the subject walks in nearly every field, and an exchanged pair lies the
other way round in nearly every field (:func:`settle_pelvis`).
"""

from __future__ import annotations

import re
import warnings

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.pieces import reach_limit, reach_miss, step_from
from kisscal.tracking.labelling.state import CLEAR_RATIO, LabelState

#: Fields either side over which a name's displacement gives the walking direction.
STEP_FIELDS = 5

#: Names whose steps a field's walking direction needs: the median of two is their mean,
#: of one that marker's own motion, and a foot in stance (no step) or swing (twice the
#: body's) is no measure of the body's; three let the median pass over one of them.
STEP_NAMES = 3

#: Anterior pelvis marker names (``LASI``, ``RASIS``) and posterior ones (``LPSI``,
#: ``SACR``, ``SAC``), by the naming convention.
PELVIS_FRONT = re.compile(r"ASI")
PELVIS_BACK = re.compile(r"PSI|SACR?$")


def pelvis_roles(names: tuple[str, ...]) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """Rows of the anterior (``*ASI*``) and posterior (``*PSI*``, ``SACR``) pelvis names
    by the naming convention; both empty unless the names hold one of each."""
    front = tuple(i for i, n in enumerate(names) if PELVIS_FRONT.search(n))
    back = tuple(i for i, n in enumerate(names) if PELVIS_BACK.search(n))
    return (front, back) if front and back else ((), ())


def ahead_fraction(pos: NDArray, a: int, b: int, forward: NDArray) -> float:
    """Fraction of the fields where both are seen in which trajectory ``a`` lies ahead of
    trajectory ``b`` along ``forward`` (F, 2), NaN without such a field."""
    ahead = np.sum((pos[a, :, :2] - pos[b, :, :2]) * forward, axis=1)
    valid = np.isfinite(ahead)
    return float(np.mean(ahead[valid] > 0)) if valid.any() else float("nan")


def settle_pelvis(
    pos: NDArray, front: tuple[int, ...], back: tuple[int, ...], forward: NDArray, sure: float
) -> list[tuple[int, int]]:
    """(front, back) name pairs to exchange: those whose trajectories lie the wrong way
    round along the walk in more than ``sure`` of the fields, when exchanging them puts
    every front name ahead of every back name in at least ``sure`` of the fields.

    ``pos`` (n, F, 3) holds the trajectory of each name (NaN where unseen), ``forward``
    (F, 2) the walking direction. The worst pair is tried first; each exchange is kept
    only if it leaves no front/back pair the wrong way round (a pelvis turned round as a
    whole, or a pair seen together too rarely, is left alone).
    """
    pos = pos.copy()
    done: list[tuple[int, int]] = []
    pairs = [(f, b) for f in front for b in back]
    for _ in range(len(pairs)):
        fraction = np.array([ahead_fraction(pos, f, b, forward) for f, b in pairs])
        if not np.any(fraction < 1.0 - sure):
            break
        f, b = pairs[int(np.nanargmin(fraction))]
        trial = pos.copy()
        trial[[f, b]] = pos[[b, f]]
        after = np.array([ahead_fraction(trial, g, c, forward) for g, c in pairs])
        if not np.all(np.nan_to_num(after, nan=1.0) >= sure):
            break
        pos = trial
        done.append((f, b))
    return done


def _wrong_way(state: LabelState, f: int, b: int, direction: NDArray) -> set[int]:
    """Long pieces named ``f`` (front) or ``b`` (back) that lie the wrong way round
    along ``direction`` against a piece of the other name in more than
    ``min_side_confidence`` of the fields both are seen in (at least
    ``min_track_length`` of them)."""
    named = state.label_of[state.long_ids]
    rows_f, rows_b = np.flatnonzero(named == f), np.flatnonzero(named == b)
    sure, least = state.params.min_side_confidence, state.params.min_track_length
    wrong: set[int] = set()
    for p in rows_f:
        for q in rows_b:
            both = state.present[p] & state.present[q] & np.isfinite(direction[:, 0])
            if both.sum() < least:
                continue
            gap = state.dense[p, both, :2] - state.dense[q, both, :2]
            if np.mean(np.sum(gap * direction[both], axis=1) > 0) < 1.0 - sure:
                wrong |= {int(state.long_ids[p]), int(state.long_ids[q])}
    return wrong


def _overlaps(state: LabelState, pieces: list[int], names: list[int]) -> bool:
    """Whether two of ``pieces``, named ``names``, share a name and a field."""
    for j in set(names):
        fields = [state.piece(t)[0] for t, n in zip(pieces, names, strict=True) if n == j]
        if fields and np.unique(np.concatenate(fields)).size < sum(x.size for x in fields):
            return True
    return False


def _carry_short(
    fields: list[NDArray], before: NDArray, after: NDArray, short: NDArray, pair: tuple[int, int]
) -> NDArray[np.int64]:
    """The names of pieces seen in ``fields``, named ``before``, once the two names of
    ``pair`` are exchanged between long pieces (``after``): a ``short`` piece that keeps
    its name while a renamed piece takes that name in one of its fields takes the pair's
    other name, and so on through the short pieces it then shares a name and field with.

    The walk cannot judge a short piece (:func:`_wrong_way` asks ``min_track_length``
    fields), but the naming that put the long pieces the wrong way round named it with
    them: kiss 3 cameras seed 442, the sacrum's 7-field piece named the right ASIS, as
    the sacrum's long piece after it, and sharing its last field with the ASIS's piece
    named the sacrum. Left with its name, it would hold it in a field of the piece the
    exchange gives it to, and the exchange would be refused (224 identity switches).
    """
    after = np.array(after, dtype=np.int64)
    moved = after != np.asarray(before)
    changed = True
    while changed:
        changed = False
        for s in np.flatnonzero(short & ~moved):
            takers = np.flatnonzero(moved & (after == after[s]))
            if any(np.intersect1d(fields[s], fields[r]).size for r in takers):
                after[s] = pair[0] if after[s] == pair[1] else pair[1]
                moved[s] = changed = True
    return after


def _fits_better(state: LabelState, f: int, b: int, wrong: list[int], worse: float = 1.0) -> bool:
    """Whether the pieces ``wrong`` named the other way round (``f`` for ``b``) fit the
    template's distances to the other names held in their fields better than as named
    (median absolute misfit), or at most ``worse`` times worse: the walk alone
    misjudged real trials (test1, newwalk: right pelvis names exchanged, silently), the
    distances and the walk together did not."""
    fields = np.zeros(state.n_fields, dtype=bool)
    for t in wrong:
        fields[state.piece(t)[0]] = True
    others = np.setdiff1d(np.arange(len(state.names)), (f, b))
    pos = state.name_pos[:, fields]
    target = state.template_distance[[f, b]][:, others][:, :, None]  # (2, m, 1)

    def misfit(at_f: NDArray, at_b: NDArray) -> float:
        d = np.linalg.norm(pos[others][None] - np.stack([at_f, at_b])[:, None], axis=3)
        e = np.abs(d - target)
        return float(np.nanmedian(e)) if np.isfinite(e).any() else np.inf

    return misfit(pos[b], pos[f]) < worse * misfit(pos[f], pos[b])


def settle_pelvis_pieces(state: LabelState) -> list[tuple[int, int]]:
    """Exchange front and back pelvis names (``*ASI*``, ``SACR``/``*PSI*``) between the
    pieces that hold them the wrong way round along the walk (:func:`walking_direction`),
    when that leaves no name on two pieces in one field; the (front, back) name pairs
    exchanged.

    A short first window that sees one ASIS and the sacrum can name them the other way
    round (their distances to the other ASIS differ by a few centimetres); later windows
    name later pieces right, so a whole-name exchange (:func:`settle_pelvis`) would only
    move the error to the other part of the trial. Exchanged only where the template's distances
    to the other names held agree (:func:`_fits_better`); short pieces named with the long
    ones go with them (:func:`_carry_short`).
    """
    front, back = pelvis_roles(state.names)
    done, direction = [], walking_direction(state.name_pos)
    for f in front:
        for b in back:
            wrong = sorted(_wrong_way(state, f, b, direction))
            if not wrong or not _fits_better(state, f, b, wrong):
                continue
            new = [b if state.label_of[t] == f else f for t in wrong]
            held = [int(t) for t in np.flatnonzero(np.isin(state.label_of, (f, b)))]
            names = [new[wrong.index(t)] if t in wrong else int(state.label_of[t]) for t in held]
            names = _carry_short(
                [state.piece(t)[0] for t in held],
                state.label_of[held],
                np.array(names),
                ~np.isin(held, state.long_ids),
                (f, b),
            ).tolist()
            if _overlaps(state, held, names):
                continue
            state.name_pos[[f, b]] = np.nan
            for t, j in zip(held, names, strict=True):
                state.name_piece(t, j)
            done.append((f, b))
    return done


def _offset_says(state: LabelState, t: int, j: int, other: int, direction: NDArray) -> bool:
    """Whether long piece ``t``, named pelvis name ``j``, lies along the walk
    (``direction``) from the other pelvis names held with it where the template puts
    name ``other`` rather than ``j``, in more than ``min_side_confidence`` of at least
    ``min_track_length`` fields."""
    front, back = pelvis_roles(state.names)
    template = state.template
    forward = template[list(front)].mean(axis=0) - template[list(back)].mean(axis=0)
    forward = forward[:2] / np.linalg.norm(forward[:2])
    fields, xyz = state.piece(t)
    with np.errstate(invalid="ignore", divide="ignore"):  # standing still: no direction
        unit = direction[fields] / np.linalg.norm(direction[fields], axis=1, keepdims=True)
    votes = []
    for k in set(front + back) - {j, other}:
        seen = np.isfinite(state.name_pos[k, fields, 0]) & np.isfinite(unit[:, 0])
        ahead = np.sum((xyz[seen, :2] - state.name_pos[k, fields[seen], :2]) * unit[seen], axis=1)
        want, rival = (template[[j, other]] - template[k])[:, :2] @ forward
        # within half the names' gap of the rival's place: a walk misjudged (turned
        # round) puts a back name ahead by the gap, as far from the front name's place
        votes.append(np.abs(ahead - rival) < np.abs(want - rival) / 2)
    votes = np.concatenate(votes) if votes else np.zeros(0, dtype=bool)
    least = state.params.min_track_length
    return votes.size >= least and votes.mean() > state.params.min_side_confidence


def _path_miss(pos: NDArray, t_fields: NDArray, t_xyz: NDArray, j: int, rigid: NDArray) -> NDArray:
    """Per side of a piece (``t_fields``, ``t_xyz``; before it, after it), how far it lies
    from name ``j``'s trajectory in ``pos`` moved on to it (:func:`~.pieces.reach_miss`),
    and the most it may (:func:`~.pieces.reach_limit`), shape (2, 2); NaN on a side
    where the trajectory has no sample."""
    first, last = int(t_fields[0]), int(t_fields[-1])
    out = np.full((2, 2), np.nan)
    for x, y in step_from(np.isfinite(pos[j, :, 0]), first, last):
        after = x > y
        at = t_xyz[-1] if after else t_xyz[0]
        out[int(after)] = reach_miss(pos[j], pos[rigid[j]], x, y, at), reach_limit(x, y)
    return out


def _continues_other(state: LabelState, t: int, j: int, other: int, rigid: NDArray) -> bool:
    """Whether piece ``t``, named ``j``, continues name ``other``'s trajectory on every
    side it has one, and on each side ``j``'s has one, ``other``'s clearly better
    (:data:`~.state.CLEAR_RATIO`): a marker's path does not jump a pelvis' width across
    a gap, and a piece named by the path it continued
    (:func:`~kisscal.tracking.labelling.spread.by_continuity`) is left between the
    other name's pieces when an exchange renames its neighbours."""
    fields, xyz = state.piece(t)
    pos = state.name_pos.copy()
    pos[j, fields] = np.nan  # the piece itself is no partner that moved
    rival, own = _path_miss(pos, fields, xyz, other, rigid), _path_miss(pos, fields, xyz, j, rigid)
    held = np.isfinite(rival[:, 0])
    return bool(
        held.any()
        and np.all(rival[held, 0] <= rival[held, 1])
        and np.all(np.isnan(own[:, 0]) | (CLEAR_RATIO * rival[:, 0] < own[:, 0]))
    )


def settle_pelvis_offsets(state: LabelState) -> bool:
    """Give a long piece named a front pelvis name the back one (or back the front) when
    its offset along the walk from the other pelvis names held says so
    (:func:`_offset_says`); the pieces holding that name in its fields take the piece's
    old name. Whether any was renamed.

    :func:`settle_pelvis_pieces` needs the two exchanged names seen together; a body fit
    from the legs alone can name the sacrum an ASIS where neither is otherwise held (kiss
    3 seed 365: turned 60 degrees by one leg and the other foot, which walking holds
    far from their standing places), and the ASIS's own piece, a few fields long, then
    takes the sacrum's name. Distances cannot tell them apart in a pelvis near
    equilateral; the other ASIS, level with an ASIS and ahead of the sacrum, can, unless
    the distances fit the exchange more than :data:`~.state.CLEAR_RATIO` times worse
    (the ratio :func:`~kisscal.tracking.labelling.spread.by_body_fit` asks of a clear
    answer) while the piece's path does not continue the other name's
    (:func:`_continues_other`): a stride moves the knees and feet tens of millimetres off
    the standing template's distances, and over a few fields they can fit the wrong name
    better (kiss 3 seed 470: the sacrum's 16-field piece, with the other ASIS, a knee, a
    shank and the feet held, 16 mm from the ASIS's template distances and 26 mm from the
    sacrum's; the sacrum's pieces on both sides continue it, the ASIS's lie 240 mm off).

    The longest pieces go first: theirs is the surest walk, and renaming them puts
    right the trajectories a shorter piece's path is judged against.
    """
    front, back = pelvis_roles(state.names)
    changed, direction = False, walking_direction(state.name_pos)
    rigid = state.rigid_pairs()
    ids = state.long_ids[np.isin(state.label_of[state.long_ids], front + back)]
    for t in ids[np.argsort(-state.n_measured[ids], kind="stable")].tolist():
        j = int(state.label_of[t])
        for other in back if j in front else front:
            if not _offset_says(state, t, j, other, direction):
                continue
            fields = state.piece(t)[0]
            held = np.flatnonzero(np.isin(state.label_of, (j, other)))
            move = [int(u) for u in held if u == t or np.isin(state.piece(u)[0], fields).any()]
            rest = [int(u) for u in held if u not in move]
            names = [other if state.label_of[u] == j else j for u in move]
            names += [int(state.label_of[u]) for u in rest]
            if _overlaps(state, move + rest, names):
                continue
            # the distances may not tell (a pelvis near equilateral) but must not clearly
            # disagree (sub_labels.c3d: an ASIS by wrongly named others), unless the
            # piece's path continues the other name's
            if not (
                _fits_better(state, j, other, move, worse=CLEAR_RATIO)
                or _continues_other(state, t, j, other, rigid)
            ):
                continue
            state.name_pos[[j, other]] = np.nan
            for u, name in zip(move + rest, names, strict=True):
                state.name_piece(u, name)
            changed = True
            break
    return changed


def _offset_across(state: LabelState, t: int, lateral: NDArray) -> NDArray[np.float64]:
    """Per field of piece ``t``, its offset across the walk from the midline of the mirror
    pairs held with it, signed as ``lateral`` (each name's template offset along the
    template's left) orders the pairs' names: which side is left, their names say (not
    the walk, which may go backwards). NaN where no pair is held or the body stands."""
    fields, xyz = state.piece(t)
    pos, mirror = state.name_pos, state.mirror_of
    # the midline: midpoints of mirror pairs (RTHI, LTHI) held together, which a narrow
    # or wide stance moves alike
    a = np.flatnonzero(mirror > np.arange(mirror.size))
    m = mirror[a]
    both = np.isfinite(pos[a][:, fields, 0] + pos[m][:, fields, 0])  # (pairs, P)
    mid = np.where(both[..., None], pos[a][:, fields, :2] + pos[m][:, fields, :2], np.nan) / 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # standing still, no pair held
        step = walking_direction(pos, fields)
        across = np.stack([-step[:, 1], step[:, 0]], axis=1) / np.linalg.norm(step, axis=1)[:, None]
        offset = np.sum((xyz[:, :2] - np.nanmean(mid, axis=0)) * across, axis=1)
    width = np.sum((pos[a][:, fields, :2] - pos[m][:, fields, :2]) * across, axis=2)
    if np.nansum(width) * np.sum(both * (lateral[a] - lateral[m])[:, None]) < 0:
        offset = -offset
    return offset


def across_walk_name(state: LabelState, t: int, names: NDArray, j: int) -> int:
    """The pelvis name of ``names`` that piece ``t``, given pelvis name ``j`` while no
    pelvis name is held in its fields, lies across the walk nearest to (its median
    offset, left of the walking direction, from the midline of the mirror pairs held
    with it, against the template's), if within half the gap to every other; -1 if
    none; ``j`` itself when the rule does not apply.

    A body fit from the legs alone turns with a thigh swinging +-25 degrees, so a lone
    pelvis marker's expected place is 100-300 mm off, and in a near-equilateral pelvis
    the sacrum's place may lie nearest an ASIS (modern 3 cameras seed 365: the left ASIS
    66 mm from the sacrum's place, 294 mm from its own). The walk swings the legs along
    it, hardly across: the side of the piece from the legs holds.
    """
    front, back = pelvis_roles(state.names)
    pelvis = np.array(front + back, dtype=int)
    fields = state.piece(t)[0]
    mirror = state.mirror_of
    rivals = names[np.isin(names, pelvis) & (names != j)]
    if mirror is None or j not in pelvis or rivals.size == 0:
        return j
    if np.isfinite(state.name_pos[pelvis][:, fields, 0]).any():
        return j
    plan = state.template[:, :2]
    forward = plan[list(front)].mean(axis=0) - plan[list(back)].mean(axis=0)
    left = np.array([-forward[1], forward[0]]) / np.linalg.norm(forward)
    lateral = plan @ left  # each name's offset across the template
    offset = _offset_across(state, t, lateral)
    seen = np.isfinite(offset)
    if seen.sum() < state.params.min_track_length:
        return j
    a = np.flatnonzero(mirror > np.arange(mirror.size))
    middle = np.mean(lateral[a] + lateral[mirror[a]]) / 2  # the template's midline
    own = np.r_[j, rivals]
    miss = np.abs(np.median(offset[seen][:, None] - (lateral[None, own] - middle), axis=0))
    gap = np.abs(lateral[own][:, None] - lateral[own][None])
    best = int(np.argmin(miss))
    return int(own[best]) if miss[best] < np.delete(gap[best], best).min() / 2 else -1


def mirror_side_name(state: LabelState, t: int, pair: NDArray) -> int:
    """The one of mirror names ``pair`` on whose side of the body's midline (the mirror
    pairs held with it) piece ``t`` lies in more than ``min_side_confidence`` of at least
    ``min_track_length`` fields, -1 if neither.

    A mirror pair's distances to a partner on the midline are equal: an ASIS by the
    sacrum alone, the other ASIS never held with it, fits both names, and the body fit
    from the legs puts it 150-350 mm from either place (modern 3 cameras seed 432: no
    ASIS named in 600 fields). Its side of the legs tells them apart.
    """
    plan, mirror = state.template[:, :2], state.mirror_of
    a = np.flatnonzero(mirror > np.arange(mirror.size))
    step = plan[a] - plan[mirror[a]]  # each pair's side axis, in either order
    axis = np.sum(step * np.sign(step @ step[0])[:, None], axis=0)
    lateral = plan @ (axis / np.linalg.norm(axis))
    side = np.sign(lateral[pair] - np.mean(lateral[a] + lateral[mirror[a]]) / 2)
    offset = _offset_across(state, t, lateral)
    seen = offset[np.isfinite(offset)]
    if side[0] == side[1] or seen.size < state.params.min_track_length:
        return -1
    share = np.mean(np.sign(seen)[:, None] == side[None], axis=0)
    sure = share > state.params.min_side_confidence
    return int(pair[np.argmax(share)]) if sure.any() else -1


def walking_direction(name_pos: NDArray, fields: NDArray | None = None) -> NDArray[np.float64]:
    """Per field (of ``fields``, every field by default), the horizontal direction the
    body moves (F, 2), not normalised: the median over the names held of their
    displacement over :data:`STEP_FIELDS` fields either side, which at given ``fields``
    stops at the trial's ends. NaN where fewer than :data:`STEP_NAMES` names hold a step
    and, without ``fields``, in the first and last :data:`STEP_FIELDS` fields."""
    k, last = STEP_FIELDS, name_pos.shape[1] - 1
    at = np.arange(last + 1) if fields is None else fields
    step = name_pos[:, np.minimum(at + k, last), :2] - name_pos[:, np.maximum(at - k, 0), :2]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # fields with no name held
        out = np.nanmedian(step, axis=0)
    out[np.isfinite(step[..., 0]).sum(axis=0) < STEP_NAMES] = np.nan
    if fields is None:
        out[:k] = out[-k:] = np.nan
    return out


def _midline(pos: NDArray, pairs: tuple, pelvis: tuple[int, ...]) -> NDArray[np.float64]:
    """Per field, a point on the body's mid-sagittal plane (F, 3): the mean of the pelvis'
    unpaired markers (the sacrum) and of its mirror pairs' midpoints where both are seen;
    NaN where neither is. One ASIS with the sacrum would put it half a pelvis aside."""
    paired = {i for pair in pairs for i in pair}
    middles = [pos[i] for i in sorted(set(pelvis) - paired)]
    middles += [0.5 * (pos[a] + pos[b]) for a, b in pairs if {a, b} <= set(pelvis)]
    if not middles:
        return np.full(pos.shape[1:], np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # fields where none is seen
        return np.nanmean(np.stack(middles), axis=0)


def lone_wrong_side(
    pos: NDArray, pairs: tuple, pelvis: tuple[int, ...], left: NDArray, min_confidence: float
) -> list[tuple[int, int]]:
    """(left, right) mirror ``pairs`` of which one name is held and its partner never
    seen, whose held trajectory (rows of ``pos``, (n, F, 3)) lies on the other side of the
    body's midline (:func:`_midline`; ``left``, (F, 2), the subject's unit left) in more
    than ``min_confidence`` of its fields: a knee named right on the left leg, its
    partner's name left free, which the pair's own check cannot see (kiss 3 cameras seed
    414, the right knee never seen by two cameras). Pairs of the ``pelvis`` are left to
    the pelvis' checks (their midline is their own midpoint)."""
    mid = _midline(pos, pairs, pelvis)
    found = []
    for a, b in pairs:
        seen_a, seen_b = np.isfinite(pos[a, :, 0]).any(), np.isfinite(pos[b, :, 0]).any()
        if seen_a == seen_b or {a, b} & set(pelvis):
            continue
        held, sign = (a, 1.0) if seen_a else (b, -1.0)
        across = sign * np.sum((pos[held, :, :2] - mid[:, :2]) * left, axis=1)
        valid = np.isfinite(across)
        if valid.any() and np.mean(across[valid] > 0) < 1.0 - min_confidence:
            found.append((a, b))
    return found
