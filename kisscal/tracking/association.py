"""Association of a field's points to the track gates (Küçük 2005 §3.3.8-3.3.9).

One-to-one over all tracks of a field (``scipy.optimize.linear_sum_assignment`` on
gate-normalised squared distances) rather than first-come nearest neighbour; a one-point
track, which has no velocity, is judged by the field after (:func:`lookahead_cost`), and so
is a track whose nearest point a rival's continuation beats (:func:`continuation_doubts`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment
from scipy.spatial import cKDTree

_FAR = 1e12
#: A rival farther than this many times the point taken from a track's quadratic
#: prediction is not weighed by its continuation (:func:`continuation_doubts`).
LOOKAHEAD_REACH = 2.0


def associate(
    predicted: NDArray,
    half_width: NDArray,
    points: NDArray,
    extra_cost: NDArray | None = None,
    distance_weight: float = 1.0,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """One-to-one assignment of points to track gates.

    Parameters
    ----------
    predicted : (T, 3) predicted positions (mm).
    half_width : (T, 3) gate half-widths per axis (mm).
    points : (M, 3) candidate points (mm).
    extra_cost : (T, M) array, optional
        Added to the cost of each pair (e.g. a look-ahead term).
    distance_weight : float
        Weight of the gate-normalised squared distance in the cost.

    Returns
    -------
    rows, cols : matched track and point indices; every pair lies inside its box gate and
    the sum of gate-normalised squared distances is minimal over all one-to-one matchings.
    """
    inside, cost = gate_costs(predicted, half_width, points, extra_cost, distance_weight)
    rows_any = np.flatnonzero(inside.any(axis=1))
    cols_any = np.flatnonzero(inside.any(axis=0))
    if rows_any.size == 0:
        empty = np.empty(0, dtype=np.int64)
        return empty, empty
    sub_inside = inside[np.ix_(rows_any, cols_any)]
    sub = np.where(sub_inside, cost[np.ix_(rows_any, cols_any)], _FAR)
    r, c = linear_sum_assignment(sub)
    keep = sub_inside[r, c]
    return rows_any[r[keep]], cols_any[c[keep]]


def one_to_one(rows: NDArray, cols: NDArray) -> bool:
    """Whether the (row, point) pairs of a gating use no row and no point twice; then the
    linear sum assignment would return exactly these pairs (any other matching pays the
    cost of a pair outside its gate)."""
    listed_rows, listed_cols = rows.tolist(), cols.tolist()
    return len(set(listed_rows)) == len(listed_rows) and len(set(listed_cols)) == len(listed_cols)


def gate_costs(
    predicted: NDArray,
    half_width: NDArray,
    points: NDArray,
    extra_cost: NDArray | None = None,
    distance_weight: float = 1.0,
) -> tuple[NDArray[np.bool_], NDArray[np.float64]]:
    """Which (track, point) pairs lie in the track's box gate (T, M), and the cost of each
    pair: ``distance_weight`` times the gate-normalised squared distance, plus
    ``extra_cost``."""
    scaled = (points[None, :, :] - predicted[:, None, :]) / half_width[:, None, :]
    inside = (np.abs(scaled) <= 1.0).all(axis=2)
    cost = distance_weight * np.einsum("tmc,tmc->tm", scaled, scaled)
    if extra_cost is not None:
        cost = cost + extra_cost
    return inside, cost


def lookahead_cost(
    start: NDArray, candidates: NDArray, later: NDArray, half_width: float
) -> NDArray[np.float64]:
    """Cost of continuing one-point tracks through each candidate, judged one field on.

    A track with one point has no velocity, so its nearest next point may be another
    marker (a heel marker moving into the place an ankle marker just left). Offline, the
    field after next is known: the pair (start, candidate) is extrapolated linearly
    (thesis eq. 3.11) and the squared distance of the nearest point there, in units of
    ``half_width``, is the cost (capped at 4 when nothing is near).

    Returns (T, M) for ``start`` (T, 3), ``candidates`` (M, 3), ``later`` (K, 3).
    """
    if later.shape[0] == 0:
        return np.zeros((start.shape[0], candidates.shape[0]))
    ahead = 2.0 * candidates[None, :, :] - start[:, None, :]  # (T, M, 3)
    # The nearest later point from a k-d tree (all T x M x K pairs took half of a
    # 75-marker trial's tracking), its squared distance as before.
    near = cKDTree(later).query(np.nan_to_num(ahead.reshape(-1, 3)))[1]
    d2 = ((ahead - later[near].reshape(ahead.shape)) ** 2).sum(axis=2)
    return np.minimum(d2 / half_width**2, 4.0)


def ambiguous_rows(
    cost: NDArray, inside: NDArray, rows: NDArray, cols: NDArray, margin: float
) -> NDArray[np.bool_]:
    """Tracks whose assignment another one-to-one choice nearly matches.

    Parameters
    ----------
    cost : (T, M) gate-normalised costs; inside : (T, M) which pairs lie in their gates;
    rows, cols : the assignment chosen (e.g. by :func:`associate`); margin : how much
    (in the units of ``cost``) another choice may cost more and still count as as likely.

    Returns
    -------
    (T,) bool: rows that could as well have exchanged their points (two assigned tracks
    whose swap costs less than ``margin`` more), have lost a point in their gate to a
    track that wanted it barely more (both marked), or leave a point in their gate
    unassigned that costs them barely more than theirs. A track that took another marker's
    point can only be told from one that did not by both sides of the field (Shafiq et al.
    2001's continuity): the tracks are cut there and blending joins the pieces.
    """
    n_rows, n_cols = cost.shape
    out = np.zeros(n_rows, dtype=bool)
    if rows.size == 0 or margin <= 0:
        return out
    c = np.where(inside, cost, np.inf)
    own = np.full(n_rows, np.inf)
    own[rows] = c[rows, cols]
    # Swaps between two assigned rows: c[i, col(k)] + c[k, col(i)] - own[i] - own[k].
    cross = c[np.ix_(rows, cols)]
    swap = cross + cross.T - own[rows][:, None] - own[rows][None, :]
    np.fill_diagonal(swap, np.inf)
    close = swap < margin
    out[rows] = close.any(axis=1)
    # An unassigned row that wanted an assigned point nearly as much as its owner.
    loser = np.ones(n_rows, dtype=bool)
    loser[rows] = False
    lost = (c[np.ix_(loser, cols)] - own[rows][None, :]) < margin  # (losers, assigned)
    out[np.flatnonzero(loser)[lost.any(axis=1)]] = True
    out[rows[lost.any(axis=0)]] = True
    # An assigned row with a free point in its gate almost as near as its own.
    free = np.ones(n_cols, dtype=bool)
    free[cols] = False
    out[rows] |= ((c[np.ix_(rows, free)] - own[rows][:, None]) < margin).any(axis=1)
    return out


def certain_rows(
    pred: NDArray,
    found: NDArray,
    points: NDArray,
    spread: NDArray,
    ratio: float,
    others: NDArray,
    lost: NDArray | None = None,
) -> NDArray[np.bool_]:
    """Which tracks took their point beyond doubt: every other point of the field lies
    more than ``ratio`` times farther from the prediction than the larger of the point
    taken and the track's own prediction error (``spread``, mm: its recent RMS miss, at
    least the measurement noise).

    A gate is as wide as a marker's speed (Küçük 2005 eq. 3.16) while a smooth marker's
    prediction misses by far less; judged by the gate, two markers closer than it are
    always a doubt (a golf club's LEDs 5 mm apart at 3 m/s), judged by the track's own
    misses they are not. ``pred``, ``found`` (T, 3) the tracks' predictions and points,
    ``points`` (M, 3) the field's, ``spread`` (T,); ``others`` (K, 3) every live track's
    prediction: a point another track predicted nearer stays a doubt (its own marker
    may have vanished and the track taken a neighbour's). ``lost`` (L, 3), the predictions
    of the live tracks that lose their point this field (not those already coasting, whose
    predictions have drifted: a swinging knee hidden five fields as it passed the other,
    TYPE-3.c3d): one within the same reach of the
    point taken could own it as well (a cluster's LED that vanished, its track predicting
    the point a neighbour's track took 12 mm away with misses of 14 mm RMS: Phoenix
    golf swing), so the point stays a doubt.
    """
    if pred.shape[0] == 0 or points.shape[0] < 2 or ratio <= 0:
        return np.zeros(pred.shape[0], dtype=bool)
    d_own = np.linalg.norm(found - pred, axis=1)
    d_all = np.linalg.norm(points[None, :, :] - pred[:, None, :], axis=2)
    # The point taken must be the nearest; the second nearest is then the nearest rival.
    nearest, d_rival = np.partition(d_all, 1, axis=1)[:, :2].T
    # Nearest to this track among all live tracks (this one's prediction is in ``others``).
    d_track = np.linalg.norm(found[:, None, :] - others[None, :, :], axis=2).min(axis=1)
    own = (d_own <= nearest + 1e-9) & (d_own <= d_track + 1e-9)
    reach = ratio * np.maximum(d_own, spread)
    if lost is not None and lost.shape[0]:
        d_lost = np.linalg.norm(found[:, None, :] - lost[None, :, :], axis=2).min(axis=1)
        own &= d_lost > reach
    return own & (d_rival > reach)


def continuation_doubts(
    history: NDArray,
    found: NDArray,
    points: NDArray,
    later: NDArray,
    least_mm: float,
) -> NDArray[np.bool_]:
    """Which tracks took a point that continues their path worse than another point
    within :data:`LOOKAHEAD_REACH` times its distance from the track's constant-acceleration
    prediction.

    On fast markers a few centimetres apart (30 Hz, a limb moving 50-180 mm a field) the
    prediction misses by about the spacing, so the nearest point may be a neighbour's. One
    field more tells them apart: a path that jumps onto a neighbour steps by the spacing
    ``d``, and its third difference (jerk) there and in the field after is about ``d``
    and ``3 d``, while the marker's own path keeps a small one (Shafiq et al. 2001's
    continuity, here over the candidate and the field after). The cost of each candidate
    ``p`` is the squared miss of the quadratic through the track's last three points, plus
    that of the quadratic through the last two and ``p`` at the nearest point of ``later``.

    Parameters
    ----------
    history : (T, 3, 3) each track's last three positions, oldest first (mm).
    found : (T, 3) the point each track took; points : (M, 3) the field's points;
    later : (K, 3) the next field's points; least_mm : a point taken nearer than this to
    the prediction is no doubt (a few times the noise).

    Returns
    -------
    (T,) bool: tracks for which a rival's continuation costs less than their point's
    (cut there: blending judges the join with both sides).
    """
    if history.shape[0] == 0 or points.shape[0] < 2 or later.shape[0] == 0:
        return np.zeros(history.shape[0], dtype=bool)
    h3, h2, h1 = history[:, 0], history[:, 1], history[:, 2]
    pred = 3.0 * h1 - 3.0 * h2 + h3
    miss = np.sum((points[None, :, :] - pred[:, None, :]) ** 2, axis=2)  # (T, M)
    own_miss = np.sum((found - pred) ** 2, axis=1)
    own = np.sum((found[:, None, :] - points[None, :, :]) ** 2, axis=2).argmin(axis=1)
    rivals = (miss < LOOKAHEAD_REACH**2 * own_miss[:, None]) & (own_miss > least_mm**2)[:, None]
    rivals[np.arange(own.size), own] = False
    out = np.zeros(history.shape[0], dtype=bool)
    t = np.flatnonzero(rivals.any(axis=1))  # the field after is weighed only where in doubt
    if t.size == 0:
        return out
    ahead = 3.0 * points[None, :, :] - (3.0 * h1[t] - h2[t])[:, None, :]  # (t, M, 3)
    on = np.sum((ahead[:, :, None, :] - later[None, None, :, :]) ** 2, axis=3).min(axis=2)
    cost = miss[t] + on
    own_cost = cost[np.arange(t.size), own[t]]
    out[t] = (rivals[t] & (cost < own_cost[:, None])).any(axis=1)
    return out


def contested_points(
    in_gate: NDArray,
    taker_pred: NDArray,
    loser_pred: NDArray,
    found: NDArray,
    fresh: NDArray,
    ratio: float,
    least_mm: float,
) -> NDArray[np.bool_]:
    """Which points taken were contested by a track left without one: (L, K) for L losers
    and K points taken.

    A loser contests a point it had in its gate and predicted nearer than the taker did
    (tiers choose in turn: a young track with a wide gate may take the point of a marker
    that appeared a field before). A ``fresh`` loser, seen the field before and with a
    velocity, also contests a point it had in its gate or predicted less than ``ratio``
    times as far as the taker, when the taker missed it by over ``least_mm``: its marker
    or the taker's vanished this field, and nothing in the field says which. On
    PhaseSpace's hand (30 Hz, LEDs 40-70 mm apart, predictions missing by 70-140 mm RMS)
    the track of a hidden LED took its neighbour's point 96 mm from its prediction while
    the neighbour's own track predicted it 102 mm away; both are cut there and blending
    judges who continues whom from both sides.

    Parameters
    ----------
    in_gate : (L, K) bool, whether each point lies in each loser's gate.
    taker_pred : (K, 3) the takers' predictions; loser_pred : (L, 3) the losers'.
    found : (K, 3) the points taken; fresh : (L,) bool.
    ratio : ``rival_ratio``; least_mm : a taker this near its point is sure of it.
    """
    d_taker = np.linalg.norm(found - taker_pred, axis=1)
    d_loser = np.linalg.norm(found[None, :, :] - loser_pred[:, None, :], axis=2)
    nearer = in_gate & (d_loser < d_taker[None, :])
    close = in_gate | (d_loser < ratio * d_taker[None, :])
    return nearer | (close & fresh[:, None] & (d_taker > least_mm)[None, :])
