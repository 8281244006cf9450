"""A rigid cluster's markers predict each other (the tracker's second look at a field).

On a fast limb at a low rate (PhaseSpace's hand at 30 Hz: LEDs 30-70 mm apart, a field's
step 60-170 mm) a track's constant-velocity or quadratic prediction misses by more than
the markers are apart, and a track that has just appeared has no velocity at all: the
nearest point is a neighbour's. The markers of a hand move together, and the points
assigned to them in a field move as they do whichever of them took which: the mean
displacement of a cluster's points, from their tracks' last positions, does not depend
on the pairing (the translation of Umeyama 1991's least-squares rigid fit). A track is
predicted by that common move of its cluster where its own prediction cannot tell its
neighbours apart, and the field is assigned again (:func:`carry`). The track's own point
of the first assignment is left out of the mean: it is the one in doubt (with it,
PhaseSpace keeps 8 net switches instead of 4).

Where the first assignment is itself wrong (a toe-off: two LEDs leap by more than they
are apart, one track takes the other's point and that one's track finds none), the mean of
its moves is wrong too: the move that carries the most of a cluster's last positions onto
the field's points, whoever took which, is found by hypothesis and check instead
(:func:`joint_moves`).

What the carried prediction still gets wrong, the cluster's distances show after the
assignment: a track whose new point changes its distance to a marker it moved with is
cut there, with that marker, for blending to judge (:func:`broken`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

#: A neighbour moved together with a track while their distance over their last
#: :data:`TOGETHER_FIELDS` shared positions stayed within this share of it now (a hand's
#: LEDs: 5-10 mm over a trial at 30-50 mm apart; over three fields, less).
TOGETHER_SHARE = 0.1
TOGETHER_FIELDS = 3


def carry(
    pred: NDArray,
    history: NDArray,
    n: NDArray,
    fresh: NDArray,
    points: NDArray,
    rows: NDArray,
    cols: NDArray,
    radius_mm: float,
    least_mm: float,
) -> bool:
    """Move to where its cluster carries it the prediction of each track that lies
    farther from there than its nearest other track (and over ``least_mm``); returns
    whether any prediction moved (``pred`` is changed in place).

    A track seen last field is carried by the mean move this field (from their last
    positions to the points of a first assignment ``rows`` -> ``cols``) of the assigned
    tracks within ``radius_mm`` that moved together with it (:func:`together`). A slow or
    well predicted track is left alone: nothing is carried that way in a field where every
    track found its point within ``least_mm`` of its prediction. Before that, and also
    where a track seen last field found none, a cluster's move found whichever track took
    which point (:func:`joint_moves`) carries its tracks where the first assignment
    explains fewer of them (:func:`_joint_carry`).

    Parameters
    ----------
    pred : (T, 3) every row's prediction; history : (T, H, 3) its last positions (nearest
    last); n : (T,) its number of points; fresh : (T,) bool, alive and seen last field.
    points : (M, 3) the field's points; rows, cols : the first assignment.
    radius_mm : ``cluster_radius_mm`` (0: nothing is carried); least_mm : a miss this
    small is no miss (a few times the noise).
    """
    rows, cols = _fresh_pairs(fresh, rows, cols)
    if radius_mm <= 0 or rows.size == 0 or np.count_nonzero(fresh) < 2:
        return False
    miss = points[cols] - pred[rows]
    missed = rows.size >= 2 and np.einsum("tc,tc->t", miss, miss).max() > least_mm**2
    # A track seen last field that found no point may have lost it to a neighbour.
    if not missed and np.count_nonzero(fresh) == rows.size:
        return False
    last = history[:, -1]
    live = np.flatnonzero(fresh)
    move = points[cols] - last[rows]
    apart = np.linalg.norm(last[live][:, None] - last[live][None], axis=2)
    np.fill_diagonal(apart, np.inf)
    spacing = np.maximum(apart.min(axis=1), least_mm)
    near = apart[:, np.searchsorted(live, rows)] < radius_mm
    args = (history, n, live, points, rows, cols, apart, spacing, radius_mm, least_mm)
    leapt = _joint_carry(pred, *args)
    # First by nearness alone; a track far from its carried place is judged again with
    # the neighbours that moved together with it (few: the costlier test).
    far = _carried_far(pred[live], last[live], near, move, spacing) & ~leapt
    if not missed or not far.any():
        return bool(leapt.any())
    far_rows = live[far]
    near = near[far] & together(history, n, far_rows, rows)
    use = _carried_far(pred[far_rows], last[far_rows], near, move, spacing[far])
    pred[far_rows[use]] = (last[far_rows] + _mean_move(near, move))[use]
    return bool(use.any() or leapt.any())


#: Candidate points per track for :func:`joint_moves`: the nearest to its prediction.
CANDIDATES = 3


def _joint_carry(
    pred: NDArray,
    history: NDArray,
    n: NDArray,
    live: NDArray,
    points: NDArray,
    rows: NDArray,
    cols: NDArray,
    apart: NDArray,
    spacing: NDArray,
    radius_mm: float,
    least_mm: float,
) -> NDArray[np.bool_]:
    """Carry (``pred`` in place) each ``live`` track by its cluster's :func:`joint_moves`
    where that move explains two members at least, more than any move of the first
    assignment ``rows`` -> ``cols`` does, finds a point that assignment left to nobody,
    and lies farther than ``spacing`` from the track's prediction; returns which (L,).

    The mean move of the points assigned (:func:`carry`) is only as right as the
    assignment: where a cluster's markers leap by more than they are apart, one track
    takes its neighbour's point and the other none, and the mean of what was assigned is
    the wrong move, which nobody contradicts. Each condition keeps the joint move from
    overruling a right assignment: a move explaining one track is its nearest point (on
    PhaseSpace, without the two, 19 of 79 carried predictions went to another LED); one
    that uses only points already taken shifts a hidden LED's track onto a neighbour's
    (without that condition, 12 of 69). A cluster must also have moved smoothly until
    this field (every member's last second difference under half its spacing): two like
    hands 100 mm apart shaken at 118 mm a field have no prediction to tell a move onto
    their own points from one onto the other hand's (without it, 126 of 948 carried
    wrong). With all, PhaseSpace carries 9 predictions, each to its own LED (the toe-off
    of field 245 among them), the shaken hands none.
    """
    last = history[live, -1]
    member = (apart < radius_mm) & together(history, n, live, live)
    np.fill_diagonal(member, True)
    found = np.full(live.size, -1)
    found[np.searchsorted(live, rows)] = cols
    tol = np.maximum(least_mm, TOGETHER_SHARE * spacing)
    args = (last, member, pred[live], points, found, tol)
    move, support, first, inliers, landed = joint_moves(*args)
    carried = last + move
    use = (support >= 2) & (support > first)  # a cluster's move explains two at least
    # Only where the move finds a point the first assignment left to nobody.
    free = np.ones(points.shape[0], dtype=bool)
    free[cols] = False
    use &= (inliers & free[landed]).any(axis=1)
    use &= np.linalg.norm(carried - pred[live], axis=1) > spacing
    # Only a cluster that moved smoothly so far (its tracks' last second differences under
    # half their spacing): one shaken faster than its markers are apart has no prediction
    # a move among its neighbours' points could be told from another cluster's by.
    h = history[live, -3:]
    accel = np.linalg.norm(h[:, 2] - 2.0 * h[:, 1] + h[:, 0], axis=1)
    smooth = (n[live] >= 3) & (accel < 0.5 * spacing)
    use &= ~(member & ~smooth[None]).any(axis=1)
    pred[live[use]] = carried[use]
    return use


def joint_moves(
    last: NDArray, member: NDArray, pred: NDArray, points: NDArray, found: NDArray, tol: NDArray
) -> tuple[NDArray, ...]:
    """The move this field of each track's cluster, whichever point any track took: the
    translation that carries the most of the cluster's last positions onto the field's
    points, refitted over those (hypothesise and verify, Fischler & Bolles 1981's RANSAC,
    with Umeyama 1991's translation as the refit). Returns the moves (L, 3), how many
    members each explains (L,; 0 where no move is the cluster's), the most a move of the
    first assignment explains (L,), which members each move explains (L, L) and the
    points they land on (L, L).

    A move is hypothesised from each member's :data:`CANDIDATES` points nearest its
    prediction (the point minus the member's last position); a member is explained where
    its last position so moved lands within its ``tol`` of a point (ties: the least sum
    of those distances). At a toe-off at 30 Hz (PhaseSpace: two LEDs 30 mm apart leap
    41 mm) the leading LED's track finds the trailing one's point 11 mm from its
    prediction and the trailing one's track finds nothing: the mean move of the points so
    assigned explains one track; the move from the leading LED's own point, both.

    Parameters
    ----------
    last : (L, 3) the tracks' last positions; member : (L, L) bool, ``member[r, i]``:
    track ``i`` belongs to ``r``'s cluster (``r`` itself included); pred : (L, 3) their
    predictions; points : (M, 3) the field's points; found : (L,) the point of each in
    the first assignment (-1: none); tol : (L,) how near a landing is.
    """
    n_live, k = last.shape[0], min(CANDIDATES, points.shape[0])
    tree = cKDTree(points)
    near = tree.query(pred, k)[1].reshape(n_live, k)
    # The first assignment's own moves lead (a track without a point: its nearest).
    near = np.c_[np.where(found >= 0, found, near[:, 0]), near]
    k += 1
    hyp = (points[near] - last[:, None]).reshape(-1, 3)  # (L*k, 3): member j's k-th
    dist, landed = tree.query(last[:, None] + hyp[None], 1)  # (L, L*k)
    hit = dist < tol[:, None]
    # A hypothesis of a member of r's cluster is r's; only members explain it.
    member_f = member.astype(float)
    support = np.where(np.repeat(member, k, axis=1), member_f @ hit, -1.0)
    residual = member_f @ np.where(hit, dist, 0.0)
    score = support - residual / (1.0 + residual.max())
    best = np.argmax(score, axis=1)
    assigned = np.zeros((n_live, k), dtype=bool)
    assigned[:, 0] = found >= 0
    first = np.where(assigned.reshape(-1)[None], support, 0.0).max(axis=1)
    # A move is no cluster's where another, apart from it, explains as many: markers
    # equally spaced along a line (walking5's condyles and knee centre, 51 mm apart) land
    # on each other's points as well when shifted by one.
    other = np.linalg.norm(hyp[None] - hyp[best][:, None], axis=2) > tol[:, None]
    rival = np.where(other, support, -1.0).max(axis=1)
    inliers = member & hit[:, best].T  # (L, L): r's members its move explains
    inliers &= (rival < support[np.arange(n_live), best])[:, None]
    moved = points[landed[:, best].T] - last[None]  # (L, L, 3)
    count = inliers.sum(axis=1)
    move = np.einsum("ri,ric->rc", inliers, moved) / np.maximum(count, 1)[:, None]
    return move, count, first, inliers, landed[:, best].T


def together(
    history: NDArray, n: NDArray, a: NDArray, b: NDArray, k: int = TOGETHER_FIELDS
) -> NDArray[np.bool_]:
    """(A, B) whether rows ``a`` and ``b`` moved together: their distance over their last
    shared positions (up to ``k``) stayed within :data:`TOGETHER_SHARE` of the last one.

    A track that has just appeared shares one position with a track that has a past, and
    nothing says they do not (a hidden LED reappearing among its cluster); two that have
    both just appeared carry nothing to each other: their first moves are nearest-point
    guesses (the first field of a trial, or a fast marker passing a new one).
    """
    d = np.linalg.norm(history[a, None, -k:] - history[None, b, -k:], axis=3)
    shared = np.minimum(np.minimum(n[a][:, None], n[b][None, :]), k)
    old = np.arange(k)[None, None, :] < (k - shared)[:, :, None]
    change = np.where(old, 0.0, np.abs(d - d[:, :, -1:])).max(axis=2)
    rigid = (shared >= 2) & (change <= TOGETHER_SHARE * d[:, :, -1])
    return rigid | ((n[a] == 1)[:, None] != (n[b] == 1)[None, :])


def _carried_far(
    pred: NDArray, last: NDArray, near: NDArray, move: NDArray, spacing: NDArray
) -> NDArray[np.bool_]:
    """Which tracks the mean ``move`` of their ``near`` neighbours carries farther from
    their prediction than ``spacing``."""
    carried = last + _mean_move(near, move)
    return near.any(axis=1) & (np.linalg.norm(carried - pred, axis=1) > spacing)


def _fresh_pairs(fresh: NDArray, rows: NDArray, cols: NDArray) -> tuple[NDArray, NDArray]:
    """The pairs of the assignment ``rows`` -> ``cols`` whose track was seen last field:
    only those have a last position a cluster's move is measured from."""
    keep = fresh[rows]
    return rows[keep], cols[keep]


def _mean_move(near: NDArray, move: NDArray) -> NDArray:
    """Mean of ``move`` (K, 3) over each row's ``near`` (T, K) entries (0 where none)."""
    count = near.sum(axis=1, keepdims=True)
    return (near @ move) / np.maximum(count, 1)


def broken(
    history: NDArray,
    n: NDArray,
    fresh: NDArray,
    points: NDArray,
    rows: NDArray,
    cols: NDArray,
    radius_mm: float,
    least_mm: float,
) -> NDArray[np.int64]:
    """Rows of the assignment ``rows`` -> ``cols`` whose point breaks their cluster: a
    neighbour (within ``radius_mm``) that moved together with the track over all its
    positions kept (:func:`together`) lies at a distance from the new point that differs from
    their last one by over :data:`TOGETHER_SHARE` of it (at least ``least_mm``).

    A track that took a neighbour's point (its own LED hidden, or the two swapped) keeps
    no distance to the markers its LED moved with. A distance alone does not say which of
    its two ends took the wrong point (with three LEDs, nothing does): both are named, the
    tracker cuts them there and blending judges each join from both sides (a right piece
    cut is joined again; a wrong one is left apart). On synthetic shaken hands and swinging
    limbs (30 Hz, LEDs hidden 1-4 fields) it takes the changes of marker along the blended
    trajectories from 92 to 63 over 30 trials; requiring every neighbour's distance to
    jump, 81.

    Parameters
    ----------
    history : (T, H, 3) every row's last positions (nearest last); n : (T,) its number of
    points; fresh : (T,) bool, alive and seen last field. points : (M, 3) the field's
    points; rows, cols : the assignment. radius_mm : ``cluster_radius_mm`` (0: nothing is
    judged); least_mm : a change this small is noise.
    """
    rows, cols = _fresh_pairs(fresh, rows, cols)
    if radius_mm <= 0 or rows.size < 2:
        return rows[:0]
    last = history[rows, -1]
    before = np.linalg.norm(last[:, None] - last[None], axis=2)
    now = np.linalg.norm(points[cols][:, None] - points[cols][None], axis=2)
    jump = np.abs(now - before) > np.maximum(TOGETHER_SHARE * before, least_mm)
    jump &= before < radius_mm  # (the diagonal never jumps)
    if not jump.any():  # most fields: no distance changed, nothing to judge (cheap)
        return rows[:0]
    # Over every position kept: two markers passing each other keep their distance for
    # a field or two about their closest approach, not for five.
    who = np.flatnonzero(jump.any(axis=1))
    jump = jump[np.ix_(who, who)] & together(history, n, rows[who], rows[who], history.shape[1])
    return rows[who[jump.any(axis=1)]]
