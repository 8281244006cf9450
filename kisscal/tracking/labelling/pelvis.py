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

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.state import LabelState

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


def _fits_better(state: LabelState, f: int, b: int, wrong: list[int]) -> bool:
    """Whether the pieces ``wrong`` named the other way round (``f`` for ``b``) fit the
    template's distances to the other names held in their fields better than as named
    (median absolute misfit): the walk alone misjudged real trials (test1, newwalk:
    right pelvis names exchanged, silently), the distances and the walk together did
    not."""
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

    return misfit(pos[b], pos[f]) < misfit(pos[f], pos[b])


def settle_pelvis_pieces(state: LabelState, direction: NDArray) -> list[tuple[int, int]]:
    """Exchange front and back pelvis names (``*ASI*``, ``SACR``/``*PSI*``) between the
    pieces that hold them the wrong way round along the walk (``direction``, (F, 2),
    e.g. :func:`~kisscal.tracking.labelling.facing.walking_direction`), when that leaves
    no name on two pieces in one field; the (front, back) name pairs exchanged.

    A short first window that sees one ASIS and the sacrum can name them the other way
    round (their distances to the other ASIS differ by a few centimetres); later windows
    name later pieces right, so a whole-name exchange (:func:`settle_pelvis`) would only
    move the error to the other part of the trial. Exchanged only where the template's distances
    to the other names held agree (:func:`_fits_better`).
    """
    front, back = pelvis_roles(state.names)
    done = []
    for f in front:
        for b in back:
            wrong = sorted(_wrong_way(state, f, b, direction))
            if not wrong or not _fits_better(state, f, b, wrong):
                continue
            new = [b if state.label_of[t] == f else f for t in wrong]
            held = [int(t) for t in np.flatnonzero(np.isin(state.label_of, (f, b)))]
            names = [new[wrong.index(t)] if t in wrong else int(state.label_of[t]) for t in held]
            if _overlaps(state, held, names):
                continue
            state.name_pos[[f, b]] = np.nan
            for t, j in zip(held, names, strict=True):
                state.name_piece(t, j)
            done.append((f, b))
    return done
