"""Two-camera markers: epipolar pairs of the blobs that multi-camera matching left over.

A marker seen by only two cameras has no third view to verify it: any blob of the other
camera within the epipolar band is as good a partner as the true one (Shafiq et al. 2001,
4.1, accept the closest, which makes ghost markers). Three checks replace the third view:

* the pair must reproject within the trial's residual limit (the band of the
  multi-camera markers, not the matching band);
* the 3D point must continue a trajectory: with points of neighbouring fields it makes
  four consecutive positions whose second differences ``p(f-1) - 2 p(f) + p(f+1)`` are
  at most ``two_camera_continuity_mm`` (:func:`continuity_mm`). A ghost pair is the
  crossing of two rays of different markers; it jumps when either marker moves, while a
  true marker moves smoothly (Küçük 2005, 3.4: the tracker's prediction gate, here with
  a constant-velocity predictor over one field);
* the trajectory must not be made of rays that other trajectories claim: a piece of
  pairs whose two rays, at its first or last field, lie on the predictions of two
  trajectories that end there is two single-view markers whose rays cross and move
  together (:mod:`kisscal.recon.claimed`); so is a piece that holds, at its end, the
  blob of a longer trajectory's own pair; its pairs are withdrawn, the blobs compete
  again. Markers lost a while before claim from where a marker of their rigid body
  carries them (:mod:`kisscal.recon.carried`).

The check applies to every two-camera pair, ambiguous or not: a blob with a single
candidate partner is not proof, because the true partner may be hidden (gait: one leg's
markers seen from one side, the other leg's from the other). Candidates that pass compete
for their blobs, smallest second difference first; each blob ends in one marker.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from kisscal._shared import n_distinct
from kisscal.dlt.triangulate import triangulate_observations
from kisscal.recon.body import RigidTriangles, body_pairs
from kisscal.recon.claimed import claimed_pieces
from kisscal.recon.epipolar import all_fundamentals, candidate_pairs
from kisscal.recon.group import (
    Solved,
    embed_fields,
    first_per_key,
    merge_groups,
    near_cameras,
    renumber,
    residual_limit_px,
    triangulate_markers,
)
from kisscal.recon.params import ReconParams

#: Points of a neighbouring field tried as a point's previous (or next) position, nearest
#: first: a marker moves less in one field than to beyond its third-nearest neighbour.
_NEIGHBOURS = 4


def continuity_mm(
    xyz_mm: NDArray[np.float64],
    field: NDArray[np.int64],
    pool_xyz_mm: NDArray[np.float64],
    pool_field: NDArray[np.int64],
    step_mm: float,
    tolerance_mm: float,
    pool_anchor: NDArray[np.bool_] | None = None,
) -> NDArray[np.float64]:
    """How well each point continues a trajectory through the pool's points.

    A point of field f continues a trajectory when, with pool points of three of the fields
    f-3..f+3, it makes four consecutive positions moving at nearly constant velocity: both
    second differences ``|a - 2 b + c|`` of the four are small. Each position is found from
    the two before it (the pool point nearest to their linear extrapolation), starting
    from one of the four pool points of field f-1 or f+1 nearest to the point, within
    ``step_mm`` of it. Three positions are not enough: the midpoint of two markers that
    move together is collinear with one marker in the field before and the other in the
    field after.

    Parameters
    ----------
    xyz_mm : ndarray, shape (n, 3)
        Points to judge and their ``field`` (n,).
    pool_xyz_mm : ndarray, shape (m, 3)
        Points they may continue and their ``pool_field`` (m,).
    step_mm : float
        Largest distance (mm) a marker moves between consecutive fields.
    tolerance_mm : float
        Largest second difference (mm) searched for.
    pool_anchor : ndarray of bool, shape (m,), optional
        Only windows holding at least one of these pool points count (default: all do).

    Returns
    -------
    ndarray, shape (n,)
        Per point, the smallest over the four-field windows of the larger of their two
        second differences (mm); inf when no window is within tolerance.

    Examples
    --------
    >>> line = np.arange(5.0)[:, None] * [10.0, 0.0, 0.0]
    >>> continuity_mm(line[2:3], np.array([2]), line, np.arange(5), 50.0, 1.0)
    array([0.])
    """
    anchor = np.ones(len(pool_field), dtype=bool) if pool_anchor is None else pool_anchor
    pool = _Pool([_Part(pool_xyz_mm, pool_field, np.arange(len(pool_field)))], tolerance_mm)
    return _continuity(xyz_mm, field, pool, step_mm, np.r_[anchor, False])[0]


def _continuity(
    xyz_mm: NDArray[np.float64],
    field: NDArray[np.int64],
    pool: _Pool,
    step_mm: float,
    anchor: NDArray[np.bool_] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """:func:`continuity_mm` through a prepared pool, whose points carry ids.

    ``anchor`` (by id, the last entry for "none") selects the windows that count.
    Returns the score per point and the windows within tolerance, one row each:
    (point row, id, id, id of the other three positions).
    """
    best = np.full(len(xyz_mm), np.inf)
    found = [np.zeros((0, 4), dtype=np.int64)]
    idx = np.flatnonzero(np.all(np.isfinite(xyz_mm), axis=1))
    for side in (-1, 1):  # a neighbour in the previous, then in the next field
        rows, q, iq = pool.neighbours(xyz_mm[idx], field[idx] + side, step_mm)
        rows = idx[rows]
        x, f = xyz_mm[rows], field[rows]
        if side > 0:  # window f..f+3: x, q, then two extrapolations
            d1, s, i_s = pool.next(x, q, f + 2)
            d2, _, i_t = pool.next(q, s, f + 3)
            windows = [(d1, d2, (iq, i_s, i_t))]
        else:  # q before x
            d_back, p, i_p = pool.next(x, q, f - 2)
            d_older, _, i_o = pool.next(q, p, f - 3)
            d_after, r, i_r = pool.next(q, x, f + 1)
            d_later, _, i_s = pool.next(x, r, f + 2)
            windows = [
                (d_back, d_older, (iq, i_p, i_o)),
                (d_back, d_after, (iq, i_p, i_r)),
                (d_after, d_later, (iq, i_r, i_s)),
            ]
        for d1, d2, ids in windows:
            score = np.maximum(d1, d2)
            if anchor is not None:
                score[~(anchor[ids[0]] | anchor[ids[1]] | anchor[ids[2]])] = np.inf
            np.minimum.at(best, rows, score)
            ok = score <= pool.tol
            found.append(np.column_stack([rows[ok], *(i[ok] for i in ids)]))
    return best, np.concatenate(found)


class _Part:
    """Points of a pool, with their ids, in one k-d tree (fields kept apart by
    :func:`embed_fields`)."""

    def __init__(
        self, xyz: NDArray[np.float64], field: NDArray[np.int64], ids: NDArray[np.int64]
    ) -> None:
        ok = np.all(np.isfinite(xyz), axis=1)
        self.xyz = np.vstack([xyz[ok], np.full((1, 3), np.nan)])  # row -1: "none found"
        self.ids = np.r_[ids[ok], -1]
        self.tree = cKDTree(embed_fields(xyz[ok], field[ok]))


class _Pool:
    """Points that may continue a trajectory, in parts built once (the known markers) or
    per round (the pairs)."""

    def __init__(self, parts: list[_Part], tol: float) -> None:
        self.parts = [p for p in parts if p.tree.n]
        self.tol = tol

    def neighbours(
        self, xyz: NDArray[np.float64], at: NDArray[np.int64], step_mm: float
    ) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.int64]]:
        """Per point, its few nearest pool points of field ``at`` within ``step_mm`` (a
        marker's own position there is among them): (point row, pool point, its id)."""
        dist, near, ids = [], [], []
        for part in self.parts:
            k = min(_NEIGHBOURS, part.tree.n)
            d, j = part.tree.query(embed_fields(xyz, at), k=k, distance_upper_bound=step_mm)
            dist.append(d.reshape(len(xyz), k))
            near.append(part.xyz[j.reshape(len(xyz), k)])
            ids.append(part.ids[j.reshape(len(xyz), k)])
        if not dist:
            return np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
        d, q, i = (np.concatenate(x, axis=1) for x in (dist, near, ids))
        if d.shape[1] > _NEIGHBOURS:  # the nearest of every part together
            keep = np.argsort(d, axis=1)[:, :_NEIGHBOURS]
            d, i = np.take_along_axis(d, keep, 1), np.take_along_axis(i, keep, 1)
            q = np.take_along_axis(q, keep[..., None], 1)
        r, c = np.nonzero(np.isfinite(d))
        return r, q[r, c], i[r, c]

    def next(
        self, a: NDArray[np.float64], b: NDArray[np.float64], at: NDArray[np.int64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
        """The pool point of field ``at`` nearest to ``2 b - a`` (the position after a, b):
        its distance (inf beyond the tolerance or where a, b are NaN), itself (NaN) and
        its id (-1)."""
        target = 2.0 * b - a
        d = np.full(len(a), np.inf)
        out = np.full((len(a), 3), np.nan)
        ids = np.full(len(a), -1, dtype=np.int64)
        ok = np.flatnonzero(np.all(np.isfinite(target), axis=1))
        for part in self.parts:
            dp, j = part.tree.query(embed_fields(target[ok], at[ok]), distance_upper_bound=self.tol)
            better = dp < d[ok]
            rows = ok[better]
            d[rows], out[rows], ids[rows] = dp[better], part.xyz[j[better]], part.ids[j[better]]
        return d, out, ids


def match_two_camera(
    marker: NDArray[np.int64],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    params: ReconParams,
    limit_px: float | None = None,
    F: NDArray[np.float64] | None = None,
    led: NDArray[np.bool_] | None = None,
    solved: Solved | None = None,
    body: RigidTriangles | None = None,
    rate_hz: float = 50.0,
) -> tuple[NDArray[np.int64], float]:
    """Make two-camera markers of the blobs with ``marker < 0`` (see module docstring).

    Parameters
    ----------
    marker : ndarray of int, shape (n,)
        Markers of the multi-camera matching (-1: unmatched); they also serve as the
        trajectories a pair may continue.
    field, camera, uv : ndarray
        The trial's 2D table (linearised px).
    dlts : ndarray, shape (n_cameras, 11)
    params : ReconParams
        ``epipolar_band_px``, ``two_camera_step_mm``, ``two_camera_continuity_mm``,
        ``reweight_iterations``.
    limit_px : float, optional
        Largest ``rms_px`` of a pair: the trial's residual limit. Default: the limit the
        candidate pairs themselves set (:func:`residual_limit_px` of their residuals), for
        a trial without multi-camera markers.
    F : ndarray, optional
        Precomputed :func:`~kisscal.recon.epipolar.all_fundamentals`.
    led : ndarray of bool, shape (n,), optional
        Blobs at an epipole (:func:`~kisscal.recon.stationary.at_epipoles`): a pair of two
        such blobs is two cameras' LED rings.
    solved : Solved, optional
        Markers of this table triangulated before (:class:`~kisscal.recon.group.Solved`).
    body : RigidTriangles, optional
        The marker set's rigid triangles (:func:`~kisscal.recon.body.body_pairs`).
    rate_hz : float
        Field rate (Hz): lost markers are carried ``params.two_camera_carry_s``.

    Returns
    -------
    marker : ndarray of int, shape (n,)
        ``marker`` with the new markers, pieces of one marker united (3D grouping),
        renumbered in field order.
    limit_px : float
        The residual limit used.
    """
    free = np.flatnonzero(marker < 0)
    out = marker.copy()
    F = all_fundamentals(dlts) if F is None else F
    a, b, _ = candidate_pairs(field[free], camera[free], uv[free], F, params.epipolar_band_px)
    a, b = free[a], free[b]
    t = triangulate_observations(
        dlts,
        np.repeat(np.arange(len(a)), 2),
        np.column_stack([camera[a], camera[b]]).ravel(),
        np.stack([uv[a], uv[b]], axis=1).reshape(-1, 2),
        len(a),
        params.reweight_iterations,
    )
    if limit_px is None:
        limit_px = residual_limit_px(t.rms_px, params)
    good = (t.rms_px <= limit_px) & ~near_cameras(t.xyz_mm, dlts, params.camera_clearance_mm)
    if led is not None:
        good &= ~(led[a] & led[b])
    a, b, xyz = a[good], b[good], t.xyz_mm[good]
    if len(a) == 0:
        return out, limit_px
    known = np.flatnonzero(marker >= 0)
    m_xyz = triangulate_markers(marker, camera, uv, dlts, params.reweight_iterations, solved).xyz_mm
    m_field = np.zeros(len(m_xyz), dtype=np.int64)
    m_field[marker[known]] = field[known]
    # a trajectory needs three fields; a shorter trial keeps the unambiguous pairs
    judge_motion = n_distinct(field) >= 3
    alone = len(dlts) <= params.two_camera_alone_max_cameras
    won = choose_pairs(a, b, xyz, field[a], m_xyz, m_field, params, judge_motion, alone)
    # a piece whose two rays other trajectories claim is a ghost: withdraw its pairs and
    # let their blobs compete again (kisscal.recon.claimed); once none is left, a piece
    # holding the blob of a longer trajectory's own pair (among the first candidates)
    rivals, with_rivals, table = (a, b, xyz), False, (field, camera, uv)
    carry = round(params.two_camera_carry_s * rate_hz), round(params.two_camera_coast_s * rate_hz)
    for _ in range(_CLAIM_ROUNDS if judge_motion else 0):
        mine = a[won], b[won], xyz[won], m_xyz, m_field, table, dlts, params
        withdrawn = claimed_pieces(*mine, rivals if with_rivals else None, *carry)
        claimed = np.flatnonzero(won)[withdrawn]
        if len(claimed) == 0:
            if with_rivals:
                break
            with_rivals = True
            continue
        keep = np.ones(len(a), dtype=bool)
        keep[claimed] = False
        a, b, xyz = a[keep], b[keep], xyz[keep]
        won = choose_pairs(a, b, xyz, field[a], m_xyz, m_field, params, judge_motion, alone)
    won = body_pairs((a, b, xyz, field[a]), won, (m_xyz, m_field), body, params)
    order = np.argsort(field[a[won]], kind="stable")
    ids = int(marker.max(initial=-1)) + 1 + np.arange(len(order))
    out[a[won][order]] = ids
    out[b[won][order]] = ids
    near = np.concatenate([m_xyz, xyz[won]]), np.concatenate([m_field, field[a[won]]])
    if _crowded(*near, len(m_xyz), params.group_radius_mm):
        # a pair may be a piece of a marker already made: unite them (pairs are within
        # the limit, and so is every union merge_groups makes)
        united = params.group_radius_mm, limit_px, params.reweight_iterations, solved
        out = merge_groups(out, field, camera, uv, dlts, *united)
    return renumber(out, field), limit_px


#: Rounds of withdrawing claimed pieces: each round frees the true pairs a ghost held (the
#: first round without two-ray claims turns to rival pairs).
_CLAIM_ROUNDS = 8


def _crowded(
    xyz: NDArray[np.float64], field: NDArray[np.int64], first_new: int, radius_mm: float
) -> bool:
    """Whether a point from index ``first_new`` on lies within ``radius_mm`` of another
    point of its field."""
    ok = np.flatnonzero(np.all(np.isfinite(xyz), axis=1))
    new = ok[ok >= first_new]
    if len(new) == 0:
        return False
    tree = cKDTree(embed_fields(xyz[ok], field[ok]))
    return bool((tree.query(embed_fields(xyz[new], field[new]), k=2)[0][:, 1] < radius_mm).any())


def choose_pairs(
    a: NDArray[np.int64],
    b: NDArray[np.int64],
    xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    known_xyz: NDArray[np.float64],
    known_field: NDArray[np.int64],
    params: ReconParams,
    judge_motion: bool = True,
    alone: bool = True,
) -> NDArray[np.bool_]:
    """Which candidate pairs (blobs ``a``, ``b``, point ``xyz`` in ``field``) become markers.

    A pair must first continue a trajectory through the known markers and the other
    candidates. Then, in rounds, each blob used once:

    * a pair that shares neither blob with another remaining pair is taken;
    * when no such pair is left, the pairs whose trajectory (four positions) holds a known
      or a taken marker are taken, best first, up to three fields further each round (a
      wrong pairing that persists over fields supports itself, but it does not continue
      the true markers' trajectories).

    Pairs still contested when neither applies (two markers whose roles the two views
    cannot tell apart over a whole stretch) are left out rather than guessed. (Preferring
    a pair that is the only candidate of one of its blobs, as a matching that explains the
    most blobs would, was tried: the lone blob is often a marker that a single camera
    sees, and the rule then picked the wrong pair as often as the right one.)

    Without ``alone`` (a rig of more than ``two_camera_alone_max_cameras`` cameras) only
    the second rule applies: pairs extend the trajectories of markers that three or more
    cameras see. Without ``judge_motion`` (a trial too short to have a trajectory) only
    the first rule applies, if ``alone``.
    """
    step, tol = params.two_camera_step_mm, params.two_camera_continuity_mm
    n_known, n = len(known_xyz), int(max(a.max(initial=-1), b.max(initial=-1))) + 1
    ids = n_known + np.arange(len(a))  # known markers are ids 0 .. n_known - 1
    known = _Part(known_xyz, known_field, np.arange(n_known))
    anchor = np.r_[np.ones(n_known, dtype=bool), np.zeros(len(a) + 1, dtype=bool)]
    alive = np.full(len(a), judge_motion or alone)
    windows = np.zeros((0, 4), dtype=np.int64)
    if judge_motion:
        pool = _Pool([known, _Part(xyz, field, ids)], tol)
        score, windows = _continuity(xyz, field, pool, step)
        alive = score <= tol
    chosen = _unshared(a, b, alive, n)
    if not alone:  # unshared pairs joined to known markers through unshared pairs only
        chosen &= _anchored(windows, chosen, chosen & False, n_known)
    used = np.zeros(n, dtype=bool)
    used[a[chosen]] = used[b[chosen]] = True
    alive &= ~used[a] & ~used[b]
    fresh = np.ones(len(a), dtype=bool)  # the first round judges every pair
    while judge_motion and alive.any():
        k = np.flatnonzero(alive & fresh)
        if len(k) == 0:
            break
        anchor[ids[chosen]] = True
        pool = _Pool(
            [known, _Part(xyz[chosen | alive], field[chosen | alive], ids[chosen | alive])], tol
        )
        score = _continuity(xyz[k], field[k], pool, step, anchor)[0]
        ok = score <= tol
        if not ok.any():
            break
        won = np.zeros(len(a), dtype=bool)
        won[k[ok][_disjoint(a[k[ok]], b[k[ok]], score[ok])]] = True
        used[a[won]] = used[b[won]] = True
        alive &= ~used[a] & ~used[b]
        chosen |= won
        # pairs freed of a rival, or joined now to a taken one through unshared pairs
        fresh = _within_reach(xyz, field, alive, won, step)
        new = _unshared(a, b, alive, n)
        if not alone:
            new &= _anchored(windows, chosen | new, chosen, n_known)
        chosen |= new
        used[a[new]] = used[b[new]] = True
        alive &= ~used[a] & ~used[b]
        fresh |= _within_reach(xyz, field, alive, new, step)
    return chosen


def _anchored(
    windows: NDArray[np.int64],
    members: NDArray[np.bool_],
    taken: NDArray[np.bool_],
    n_known: int,
) -> NDArray[np.bool_]:
    """Pairs among ``members`` joined to a known marker or a ``taken`` pair through
    windows (rows: point, three ids) made of known markers and ``members`` alone."""
    n = n_known + len(members)
    node = np.r_[np.ones(n_known, dtype=bool), members, False]  # id -1: none
    w = windows[node[n_known + windows[:, 0]] & np.all(node[windows[:, 1:]], axis=1)]
    src = np.repeat(n_known + w[:, 0], 3)
    graph = coo_matrix((np.ones(len(src)), (src, w[:, 1:].ravel())), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    anchored = np.zeros(label.max(initial=0) + 1, dtype=bool)
    anchored[label[:n_known]] = True
    anchored[label[n_known:][taken]] = True
    return members & anchored[label[n_known:]]


def _within_reach(
    xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    among: NDArray[np.bool_],
    new: NDArray[np.bool_],
    step_mm: float,
) -> NDArray[np.bool_]:
    """Points of ``among`` that a ``new`` point could join in a four-field window: within
    three fields of it and ``step_mm`` per field apart."""
    out = np.zeros(len(xyz), dtype=bool)
    rows = np.flatnonzero(among & np.all(np.isfinite(xyz), axis=1))
    if len(rows) == 0 or not new.any():
        return out
    tree = cKDTree(embed_fields(xyz[rows], field[rows]))
    for shift in (-3, -2, -1, 1, 2, 3):
        at = embed_fields(xyz[new], field[new] + shift)
        hits = tree.query_ball_point(at, abs(shift) * step_mm)
        out[rows[np.concatenate([np.asarray(h, dtype=np.int64) for h in hits])]] = True
    return out


def _unshared(
    a: NDArray[np.int64], b: NDArray[np.int64], alive: NDArray[np.bool_], n: int
) -> NDArray[np.bool_]:
    """Alive pairs that share neither blob with another alive pair."""
    degree = np.bincount(np.concatenate([a[alive], b[alive]]), minlength=n)
    return alive & (degree[a] == 1) & (degree[b] == 1)


def _disjoint(
    a: NDArray[np.int64], b: NDArray[np.int64], score: NDArray[np.float64]
) -> NDArray[np.bool_]:
    """Pairs chosen best score first so that every blob is used once (vectorised rounds:
    each round takes every pair that is the best remaining pair of both its blobs)."""
    chosen = np.zeros(len(a), dtype=bool)
    alive = np.ones(len(a), dtype=bool)
    n = int(max(a.max(initial=-1), b.max(initial=-1))) + 1
    # one strict order of the pairs (score, then index), the same at both blobs: the first
    # remaining pair then wins at both and every round takes one at least (equal scores
    # ranked by position in the blob list could deadlock)
    rank = np.empty(len(a), dtype=np.int64)
    rank[np.lexsort((np.arange(len(a)), score))] = np.arange(len(a))
    while alive.any():
        k = np.flatnonzero(alive)
        best = np.full(n, -1, dtype=np.int64)
        first = first_per_key(np.concatenate([a[k], b[k]]), np.concatenate([rank[k]] * 2))
        best[np.concatenate([a[k], b[k]])[first]] = np.concatenate([k, k])[first]
        won = k[(best[a[k]] == k) & (best[b[k]] == k)]
        chosen[won] = True
        used = np.zeros(n, dtype=bool)
        used[a[won]] = used[b[won]] = True
        alive &= ~used[a] & ~used[b]
    return chosen
