"""Where a marker that left the views is: carried along by a marker of its rigid body.

A trajectory that ends (its marker seen by fewer than two cameras from then on) has no
constant-velocity prediction worth having a second later: walking, a pelvis marker's
vertical velocity alone turns round twice a stride. The markers of one segment, though,
move as one rigid body (Cappozzo et al. 1995): the offset from the lost marker to another
marker of its segment, steady over the fields before it was lost, stays nearly the same
for a while after, so the lost marker is where its companion's trajectory carries that
offset. This is the prediction :mod:`kisscal.recon.claimed` needs when two markers, each
seen by one camera only, have been lost for longer than a field or two when their rays
start to cross (a pelvis seen from two sides: one anterior superior iliac spine marker
by one camera, the other by another, the sacrum marker carrying both).

:func:`links` joins the points of consecutive fields into trajectories; :func:`carried`
carries each trajectory's end along the steady companion that goes on longest.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from kisscal.recon.group import embed_fields

#: Fields over which a companion's offset must have stayed steady (back from the end).
_STEADY_FIELDS = 3

#: Points of the end's field tried as its companion, nearest first.
_COMPANIONS = 4


def links(
    xyz: NDArray[np.float64], field: NDArray[np.int64], step_mm: float, tolerance_mm: float
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """The next and the previous point (index, -1 none) of each point on its trajectory.

    First the mutually nearest points of consecutive fields within ``step_mm``; then a
    point with a previous one goes on to the point of the next field nearest to its
    constant-velocity prediction, within ``tolerance_mm``, or nowhere (its marker left:
    the nearest point is another marker's). Each point has one previous, the one whose
    prediction it is nearest to.
    """
    n = len(xyz)
    nxt, prv = np.full(n, -1, dtype=np.int64), np.full(n, -1, dtype=np.int64)
    ok = np.flatnonzero(np.all(np.isfinite(xyz), axis=1))
    if len(ok) < 2:
        return nxt, prv
    tree = cKDTree(embed_fields(xyz[ok], field[ok]))
    near = []
    for side in (1, -1):
        d, j = tree.query(embed_fields(xyz[ok], field[ok] + side), distance_upper_bound=step_mm)
        out = np.full(n, -1, dtype=np.int64)
        out[ok[np.isfinite(d)]] = ok[j[np.isfinite(d)]]
        near.append(out)
    after, before = near
    mutual = np.flatnonzero(after >= 0)
    mutual = mutual[before[after[mutual]] == mutual]
    plain = np.full(n, -1, dtype=np.int64)
    plain[after[mutual]] = mutual  # the previous point, by nearness alone
    has = ok[plain[ok] >= 0]
    go = np.full(n, -1, dtype=np.int64)
    go[mutual] = after[mutual]
    go[has] = -1
    d, j = tree.query(
        embed_fields(2.0 * xyz[has] - xyz[plain[has]], field[has] + 1),
        distance_upper_bound=tolerance_mm,
    )
    go[has[np.isfinite(d)]] = ok[j[np.isfinite(d)]]
    dist = np.full(n, np.inf)
    dist[has[np.isfinite(d)]] = d[np.isfinite(d)]
    src = np.flatnonzero(go >= 0)
    src = src[np.lexsort((dist[src], go[src]))]  # per next point, the nearest first
    first = np.r_[True, go[src][1:] != go[src][:-1]]
    nxt[src[first]] = go[src[first]]
    prv[go[src[first]]] = src[first]
    return nxt, prv


def _walk(chain: NDArray[np.int64], start: NDArray[np.int64], steps: int) -> NDArray[np.int64]:
    """``steps`` links along ``chain`` from each ``start`` (-1 where the chain ends)."""
    at = start.copy()
    for _ in range(steps):
        at = np.where(at >= 0, chain[np.maximum(at, 0)], -1)
    return at


def _lasts(chain: NDArray[np.int64], start: NDArray[np.int64], most: int) -> NDArray[np.int64]:
    """Links along ``chain`` from each ``start`` before it ends, up to ``most``."""
    n = np.zeros(len(start), dtype=np.int64)
    at = start.copy()
    for _ in range(most):
        at = np.where(at >= 0, chain[np.maximum(at, 0)], -1)
        if not (at >= 0).any():
            break
        n += at >= 0
    return n


def _companions(
    xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    chains: tuple[NDArray[np.int64], NDArray[np.int64]],
    end: NDArray[np.int64],
    step_mm: float,
    tolerance_mm: float,
    fields: int,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """For each trajectory ``end``, its companion (see :func:`carried`): the ends that have
    one, and their companions."""
    on, back = chains
    ok = np.flatnonzero(np.all(np.isfinite(xyz), axis=1))
    tree = cKDTree(embed_fields(xyz[ok], field[ok]))
    k = min(_COMPANIONS + 1, len(ok))
    _, j = tree.query(embed_fields(xyz[end], field[end]), k=k, distance_upper_bound=step_mm)
    cand = np.where(j < len(ok), ok[np.minimum(j, len(ok) - 1)], -1).reshape(len(end), k)
    cand[cand == end[:, None]] = -1
    old = _walk(back, end, _STEADY_FIELDS)
    old_c = _walk(back, cand.ravel(), _STEADY_FIELDS).reshape(cand.shape)
    drift = np.linalg.norm(
        (xyz[end][:, None] - xyz[np.maximum(cand, 0)]) - (xyz[old][:, None] - xyz[old_c]), axis=2
    )
    fine = (cand >= 0) & (old[:, None] >= 0) & (old_c >= 0) & (drift <= tolerance_mm)
    lasts = _lasts(on, np.where(fine, cand, -1).ravel(), fields).reshape(cand.shape)
    # the steady companion that goes on longest (the sacrum for an iliac spine, not the
    # other spine that is lost a field later), the steadier of those that last as long
    rank = np.where(fine & (lasts >= 2), lasts - drift / (2.0 * tolerance_mm), -np.inf)
    best = rank.argmax(axis=1)
    row = np.arange(len(end))
    has = np.isfinite(rank[row, best])
    return end[has], cand[row, best][has]


def carried(
    xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    chains: tuple[NDArray[np.int64], NDArray[np.int64]],
    step_mm: float,
    tolerance_mm: float,
    side: int,
    fields: int,
    coast: int = 0,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]]:
    """Positions of each trajectory's end carried ``2 .. fields`` fields on (``side`` +1)
    or back (-1) by its companion; ``chains`` are the points' :func:`links`. An end with
    no companion (its whole segment lost with it) coasts ``2 .. coast`` fields on its own
    velocity over the :data:`_STEADY_FIELDS` fields before it (:func:`coasted`).

    The companion is one of the points of the end's field nearest to it whose offset to
    the ending trajectory changed by at most ``tolerance_mm`` over the
    :data:`_STEADY_FIELDS` fields before the end: of those, the one whose trajectory goes
    on longest past the end. The carried position is the end plus the companion's
    displacement since, for as long as the companion goes on. (One field on, the
    constant-velocity prediction of :mod:`kisscal.recon.claimed` stands.)

    Returns
    -------
    xyz : ndarray, shape (k, 3)
        Carried positions, with their ``field`` (k,) and the index of the end (k,).
    """
    empty = np.zeros((0, 3)), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    on, back = chains if side > 0 else chains[::-1]
    ends = np.flatnonzero((on < 0) & (back >= 0))
    if len(ends) == 0 or fields < 2:
        return empty
    end, comp = _companions(xyz, field, (on, back), ends, step_mm, tolerance_mm, fields)
    lone = _alone(xyz, field, on, np.setdiff1d(ends, end), step_mm)
    lone = coasted(xyz, field, back, lone, side, min(coast, fields))
    out_xyz, out_field, out_end = [lone[0]], [lone[1]], [lone[2]]
    at = on[comp]
    for _ in range(2, fields + 1):
        at = np.where(at >= 0, on[np.maximum(at, 0)], -1)
        live = at >= 0
        if not live.any():
            break
        out_xyz.append(xyz[end[live]] + xyz[at[live]] - xyz[comp[live]])
        out_field.append(field[at[live]])
        out_end.append(end[live])
    return np.concatenate(out_xyz), np.concatenate(out_field), np.concatenate(out_end)


def _alone(
    xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    on: NDArray[np.int64],
    end: NDArray[np.int64],
    step_mm: float,
) -> NDArray[np.int64]:
    """The ends ``end`` with no point of their field within ``step_mm`` whose trajectory
    goes on (``on``): nothing of the body near them stays in view."""
    going = np.flatnonzero(np.all(np.isfinite(xyz), axis=1) & (on >= 0))
    if len(going) == 0:
        return end
    tree = cKDTree(embed_fields(xyz[going], field[going]))
    d, _ = tree.query(embed_fields(xyz[end], field[end]), distance_upper_bound=step_mm)
    return end[~np.isfinite(d)]


def coasted(
    xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    back: NDArray[np.int64],
    end: NDArray[np.int64],
    side: int,
    coast: int,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]]:
    """Positions of trajectory ends ``end`` coasting ``2 .. coast`` fields on (``side``)
    at their mean velocity over the :data:`_STEADY_FIELDS` fields before (``back``: the
    links the other way); ends with a shorter past stay. When a pelvis leaves the views
    (each marker seen by one camera at most), no companion carries its markers; walking,
    it moves at nearly constant velocity for a tenth of a second (its vertical bob peaks near
    3 m/s^2: 15 mm off after 0.1 s), and that is as far as they coast. Returns positions,
    fields and ends as :func:`carried`."""
    old = _walk(back, end, _STEADY_FIELDS)
    end, old = end[old >= 0], old[old >= 0]
    step = (xyz[end] - xyz[old]) / _STEADY_FIELDS
    k = np.arange(2, max(coast, 1) + 1)
    pos = xyz[end][:, None] + step[:, None] * k[:, None]
    at = field[end][:, None] + side * k
    return pos.reshape(-1, 3), at.ravel(), np.repeat(end, len(k))
