"""The walks of the chain fill (:mod:`.raychain`): from each side of a gap, the points
on the marker's rays followed field by field as its segment moves, and the point the two
walks settle on.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def walk_picks(
    cands: dict[int, NDArray],
    guide: NDArray,
    start: NDArray,
    k_prev: int,
    ks: list[int],
    coast: int,
) -> tuple[dict[int, int], set[int]]:
    """Per gap field offset of ``ks`` (in the order walked), the candidate (index into
    ``cands[k]``, an (p, 3) array) nearest the path continued from ``start`` (at offset
    ``k_prev``): moved as the segment's partner ``guide`` ((n + 2, 3), offsets -1..n)
    moved, if within 30 mm per field walked (100 mm at most); none where the runner-up
    is less than twice as far. And the offsets where the walk refused a candidate as
    another branch (over 30 mm from its pick, or out of reach within ``coast`` fields
    of its last point) or its continuation (within 30 mm, half as far as the path): where a
    drifting length (thigh to shank) leaves only the ray's other depth, a point alone
    is not the marker (modern 3 seed 332 RTHI 465-517: 87-262 mm off, expecting 2.47)."""
    out: dict[int, int] = {}
    refused: set[int] = set()
    prev, ref, k_ref = start, np.zeros((0, 3)), k_prev
    for k in ks:
        gap = abs(k - k_prev)
        step = guide[k + 1] - guide[k_prev + 1]
        pred = prev + np.nan_to_num(step)
        dist = np.linalg.norm(cands[k] - pred, axis=1)
        to_ref = np.linalg.norm(cands[k][:, None] - ref[None], axis=2).min(axis=1, initial=np.inf)
        other = (abs(k - k_ref) == 1) & (to_ref <= 30.0) & (2.0 * to_ref < dist)
        dist = np.where(other, np.inf, dist)
        i, reach = int(np.argmin(dist)), min(30.0 * gap, 100.0)
        picked = dist[i] <= reach and not np.any(np.delete(dist, i) < 2.0 * dist[i])
        if picked:  # another branch: farther from the pick than a field's motion
            other |= np.linalg.norm(cands[k] - cands[k][i], axis=1) > 30.0
        elif gap - 1 <= coast:
            other |= dist > reach
        ref, k_ref = cands[k][other], k
        refused |= {k} if other.any() else set()
        if picked:
            out[k] = i
            prev, k_prev = cands[k][i], k
    return out, refused


def connected_picks(picks: dict[int, int], start: int, coast: int) -> set[int]:
    """The gap offsets of a walk's ``picks`` (in the order walked, from offset
    ``start``, the gap's edge) reached with no more than ``coast`` fields in a row
    without a pick: farther on, its predicted path has drifted for too long to tell two
    near points apart."""
    out: set[int] = set()
    last = start
    for k in picks:
        if abs(k - last) - 1 > coast:
            break
        out.add(k)
        last = k
    return out


def agreed_pick(i: int | None, j: int | None, near_i: bool, near_j: bool) -> int | None:
    """The candidate the two walks from a gap's sides (picks ``i`` forward, ``j``
    backward; ``near_*`` whether unbroken from their edge, :func:`connected_picks`) settle
    on: the one both took, or the one a walk unbroken from its side took where the
    other walk took none (the sample beyond the gap's far side may be another
    marker's: a walk from it finds no path)."""
    if i is not None and i == j:
        return i
    if i is not None and near_i and j is None:
        return i
    if j is not None and near_j and i is None:
        return j
    return None


def told(cands: dict[int, list], limit: float) -> set[int]:
    """The gap offsets of ``cands`` (per offset, its points (xyz, expected error along
    the ray, row)) a walk reaches from its side without passing a field whose depths are
    untold (:func:`untold`): before the first such field, or after the last. There the
    ray grazes the partners' spheres and its two depths meet: past it, a walk keeping to
    the nearest point may go on along the other depth as smoothly as along the marker's,
    and two walks that both passed one agree on nothing (modern 3 seed 430: RTIB, one
    partner, both walks onto the other depth, 40 fields 93-160 mm off expecting 2.6-4.4)."""
    order = sorted(cands)
    blind = [k for k in order if untold(cands[k], limit)]
    return {k for k in order if not blind or k < blind[0] or k > blind[-1]}


def untold(points: list, limit: float) -> bool:
    """Whether a field's ray ``points`` (xyz, expected error, row) leave its depth
    untold: two of them nearer each other than three times the largest expected error,
    and that over ``limit`` mm (a point alone is the only depth the lengths allow)."""
    worst = max(p[1] for p in points)
    if worst <= limit:
        return False
    xyz = np.array([p[0] for p in points])
    apart = np.linalg.norm(xyz[:, None] - xyz[None], axis=2) + np.diag(np.full(len(xyz), np.inf))
    return bool(apart.min() < 3.0 * worst)
