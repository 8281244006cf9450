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
carries each trajectory's end along its steadiest companion.
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

    A point's next is the point of the next field nearest to its constant-velocity
    prediction (from the nearest point of the field before within ``step_mm``, or itself),
    within ``tolerance_mm``; a link holds when it is also the next point's previous, found
    the same way backwards.
    """
    n = len(xyz)
    ends = []
    ok = np.flatnonzero(np.all(np.isfinite(xyz), axis=1))
    out = np.full((2, n), -1, dtype=np.int64)
    if len(ok) < 2:
        return out[0], out[1]
    tree = cKDTree(embed_fields(xyz[ok], field[ok]))
    for side in (1, -1):
        d, j = tree.query(embed_fields(xyz[ok], field[ok] - side), distance_upper_bound=step_mm)
        prev = np.where(np.isfinite(d)[:, None], xyz[ok][np.minimum(j, len(ok) - 1)], xyz[ok])
        d, j = tree.query(
            embed_fields(2.0 * xyz[ok] - prev, field[ok] + side), distance_upper_bound=tolerance_mm
        )
        near = np.full(n, -1, dtype=np.int64)
        hit = np.isfinite(d)
        near[ok[hit]] = ok[j[hit]]
        ends.append(near)
    nxt, prv = ends
    mutual = nxt >= 0
    mutual[mutual] = prv[nxt[mutual]] == np.flatnonzero(mutual)
    out[0, mutual] = nxt[mutual]
    out[1, nxt[mutual]] = np.flatnonzero(mutual)
    return out[0], out[1]


def _walk(chain: NDArray[np.int64], start: NDArray[np.int64], steps: int) -> NDArray[np.int64]:
    """``steps`` links along ``chain`` from each ``start`` (-1 where the chain ends)."""
    at = start.copy()
    for _ in range(steps):
        at = np.where(at >= 0, chain[np.maximum(at, 0)], -1)
    return at


def carried(
    xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    step_mm: float,
    tolerance_mm: float,
    side: int,
    fields: int,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]]:
    """Positions of each trajectory's end carried ``2 .. fields`` fields on (``side`` +1)
    or back (-1) by its companion.

    The companion is, of the points of the end's field nearest to it, the one whose
    trajectory goes on past the end and whose offset to the ending trajectory changed
    least (at most ``tolerance_mm``) over the :data:`_STEADY_FIELDS` fields before it;
    the carried position is the end plus the companion's displacement since. (One field
    on, the constant-velocity prediction of :mod:`kisscal.recon.claimed` stands.)

    Returns
    -------
    xyz : ndarray, shape (k, 3)
        Carried positions, with their ``field`` (k,) and the index of the end (k,).
    """
    empty = np.zeros((0, 3)), np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    nxt, prv = links(xyz, field, step_mm, tolerance_mm)
    on, back = (nxt, prv) if side > 0 else (prv, nxt)
    end = np.flatnonzero((on < 0) & (back >= 0))
    if len(end) == 0:
        return empty
    ok = np.flatnonzero(np.all(np.isfinite(xyz), axis=1))
    tree = cKDTree(embed_fields(xyz[ok], field[ok]))
    k = min(_COMPANIONS + 1, len(ok))
    _, j = tree.query(embed_fields(xyz[end], field[end]), k=k, distance_upper_bound=step_mm)
    cand = np.where(j < len(ok), ok[np.minimum(j, len(ok) - 1)], -1).reshape(len(end), k)
    cand[cand == end[:, None]] = -1
    old = _walk(back, end, _STEADY_FIELDS)
    old_c = _walk(back, cand.ravel(), _STEADY_FIELDS).reshape(cand.shape)
    fine = (cand >= 0) & (old[:, None] >= 0) & (old_c >= 0) & (on[np.maximum(cand, 0)] >= 0)
    drift = np.linalg.norm(
        (xyz[end][:, None] - xyz[np.maximum(cand, 0)]) - (xyz[old][:, None] - xyz[old_c]), axis=2
    )
    drift = np.where(fine, drift, np.inf)
    best = drift.argmin(axis=1)
    steady = drift[np.arange(len(end)), best] <= tolerance_mm
    end, comp = end[steady], cand[np.arange(len(end)), best][steady]
    out_xyz, out_field, out_end = [], [], []
    at = on[comp]
    for _ in range(2, fields + 1):
        at = np.where(at >= 0, on[np.maximum(at, 0)], -1)
        live = at >= 0
        if not live.any():
            break
        out_xyz.append(xyz[end[live]] + xyz[at[live]] - xyz[comp[live]])
        out_field.append(field[at[live]])
        out_end.append(end[live])
    if not out_xyz:
        return empty
    return np.concatenate(out_xyz), np.concatenate(out_field), np.concatenate(out_end)
