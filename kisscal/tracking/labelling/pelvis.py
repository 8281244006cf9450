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
