"""A foot's held pieces kept beside the pieces that win its names.

The foot contest (:func:`~kisscal.tracking.labelling.feet.settle_feet`) gives each foot
name one candidate: a held name's whole trajectory or an unnamed long piece near the
shank. A foot whose marker was tracked in pieces at different times offers the contest
the same marker twice; the piece seen with the shank wins the name and the other, a
later stretch of the same marker, was left unnamed (three cameras, the knee seen by two
in no field: the right foot named over 107 of its 395 fields). Two pieces of one marker
are never seen together, and the foot's markers stay rigid to each other (Winter 2009),
so a held candidate the best way leaves unnamed keeps its name when it shares no field
with its name's winner and its distances to the foot's other holders fit the template.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np
from numpy.typing import NDArray


def fit_mm(dist: NDArray, target: NDArray, use: NDArray) -> NDArray:
    """RMS (mm) of each way's (rows) distances ``dist`` against ``target`` over the pairs
    in ``use``; infinite when a pair used was never seen together or none is used."""
    miss = np.where(use, dist - target, 0.0)
    seen = np.isfinite(miss).all(axis=-1) & use.any(axis=-1)
    total = np.where(np.isfinite(miss), miss**2, 0.0).sum(axis=-1)
    return np.where(seen, np.sqrt(total / np.maximum(use.sum(axis=-1), 1)), np.inf)


def continued(
    choice: NDArray,
    held_at: NDArray,
    evidence: tuple,
    order: list[tuple[int, int]],
    tolerance: float,
) -> dict[int, int]:
    """Held candidates the best way leaves unnamed that keep their name too.

    Parameters
    ----------
    choice : (k,) int array
        The best way: each foot name's candidate, -1 for none.
    held_at : (h,) int array
        The foot name (position) of each held candidate (candidates ``0 .. h-1``).
    evidence : tuple
        The candidates' median distances (c, c), whether each trails each (c, c) along
        the walk, where each is seen (c, F), and the template's distances between the
        foot names (k, k).
    order : list of (int, int)
        Positions among the foot names of the (front, back) pairs held to their order
        along the walk (the toe and the heel; the ankle and either,
        :func:`~kisscal.tracking.labelling.footwalk.ordered_pairs`).
    tolerance : float
        ``label_segment_tolerance_mm``: RMS fit of the kept candidates' distances.

    Returns
    -------
    dict
        Foot name position to held candidate, for the largest set of held candidates that
        share no field with their name's winner and whose distances to the foot's
        holders (pairs seen together, one at least) fit within ``tolerance`` with no
        pair of ``order`` the other way round; empty when none does.
    """
    d, behind, seen, want = evidence
    loose = [(int(i), c) for c, i in enumerate(held_at) if c not in choice and choice[i] >= 0]
    loose = [(i, c) for i, c in loose if not (seen[c] & seen[choice[i]]).any()]
    given = [(int(i), int(c)) for i, c in enumerate(choice) if c >= 0]
    for keep in (k for n in range(len(loose), 0, -1) for k in combinations(loose, n)):
        pairs = [(x, y) for x in given + list(keep) for y in keep if x[0] != y[0]]
        dist = np.array([d[x[1], y[1]] for x, y in pairs])
        target = np.array([want[x[0], y[0]] for x, y in pairs])
        use = np.isfinite(dist)
        wrong_way = any(behind[x[1], y[1]] for x, y in pairs if (x[0], y[0]) in order)
        wrong_way |= any(behind[y[1], x[1]] for x, y in pairs if (y[0], x[0]) in order)
        if use.any() and fit_mm(dist, target, use) <= tolerance and not wrong_way:
            return dict(keep)
    return {}
