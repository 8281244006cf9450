"""Rigid geometry of point sets: the fits and correspondences labelling is built on
(Kabsch 1976 fits, Hungarian assignment after Kuhn 1955, classical MDS after Torgerson
1952, 2-opt name exchanges). Everything here works on numpy arrays; nothing knows about
tracks or sessions.
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment


def _cube_rotations() -> NDArray[np.float64]:
    """The 24 proper rotations that map coordinate axes onto coordinate axes."""
    mats = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            m[np.arange(3), perm] = signs
            if np.linalg.det(m) > 0:
                mats.append(m)
    return np.array(mats)


_CUBE = _cube_rotations()


def _principal_frame(points: NDArray) -> NDArray[np.float64]:
    _, vecs = np.linalg.eigh(np.cov(points.T))
    if np.linalg.det(vecs) < 0:
        vecs[:, 0] = -vecs[:, 0]
    return vecs


def kabsch(source: NDArray, target: NDArray) -> tuple[NDArray, NDArray]:
    """Proper rotation R and translation t minimising sum |R s + t - g|² (no reflection).

    Parameters
    ----------
    source, target : (k, 3) arrays
        Corresponding points, k >= 3.

    Returns
    -------
    r : (3, 3) array
        Rotation, det +1.
    t : (3,) array

    References
    ----------
    Kabsch 1976 (the SVD solution; the sign of the last singular vector rules out a
    reflection).

    Examples
    --------
    >>> import numpy as np
    >>> pts = np.array([[0.0, 0, 0], [100, 0, 0], [0, 50, 0], [0, 0, 20]])
    >>> turn = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])  # 90 degrees about z
    >>> r, t = kabsch(pts, pts @ turn.T + [1, 2, 3])
    >>> bool(np.allclose(r, turn)), np.round(t, 6).tolist()
    (True, [1.0, 2.0, 3.0])
    """
    cs, ct = source.mean(axis=0), target.mean(axis=0)
    h = (source - cs).T @ (target - ct)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return r, ct - r @ cs


def match_to_template(
    points: NDArray, template: NDArray, outlier_mm: float, iterations: int = 10
) -> tuple[NDArray[np.int64], float]:
    """Correspondence of ``points`` (k, 3) to ``template`` (n, 3) under a rigid motion.

    Returns the template index per point (-1 when unmatched or farther than
    ``outlier_mm`` after the fit) and the RMS distance of the matched points (mm).

    Examples
    --------
    >>> import numpy as np
    >>> template = np.array([[0.0, 0, 0], [300, 0, 0], [0, 120, 0], [0, 0, 60]])
    >>> assign, rms = match_to_template(template[[2, 0, 3, 1]] + 500.0, template, 20.0)
    >>> assign.tolist(), round(rms, 6)
    ([2, 0, 3, 1], 0.0)
    """
    found = rigid_matches(points, template, outlier_mm, iterations)
    if not found:
        return np.full(points.shape[0], -1, dtype=np.int64), float("inf")
    return found[0]


def _squared_distances(points: NDArray, r: NDArray, t: NDArray, template: NDArray) -> NDArray:
    moved = points @ r.T + t
    return ((moved[:, None, :] - template[None, :, :]) ** 2).sum(axis=2)


def _descend(
    points: NDArray, template: NDArray, r: NDArray, t: NDArray, cap: float, iterations: int
) -> tuple[NDArray, NDArray]:
    """Alternate assignment and Kabsch fit from the pose (r, t) until the pairs repeat."""
    prev = None
    for _ in range(iterations):
        d2 = _squared_distances(points, r, t, template)
        rows, cols = linear_sum_assignment(np.minimum(d2, cap))
        good = d2[rows, cols] < cap
        if good.sum() < 3:
            break
        key = tuple(cols[good]) + tuple(rows[good])
        if key == prev:
            break
        prev = key
        r, t = kabsch(points[rows[good]], template[cols[good]])
    return r, t


def rigid_matches(
    points: NDArray, template: NDArray, outlier_mm: float, iterations: int = 10
) -> list[tuple[NDArray[np.int64], float]]:
    """Distinct rigid correspondences of ``points`` to ``template``, best first.

    Iterated Hungarian assignment and Kabsch fit, started from the 24 axis-aligned
    orientations of the two principal-axis frames; each start gives one local optimum.
    Returns (template index per point or -1, RMS distance of the matched points in mm).

    References
    ----------
    Kuhn 1955 (the Hungarian assignment); Kabsch 1976.
    """
    k = points.shape[0]
    if k < 3:
        return []
    cp, ctm = points.mean(axis=0), template.mean(axis=0)
    fp, ft = _principal_frame(points), _principal_frame(template)
    cap = outlier_mm**2
    results: dict[tuple, tuple[float, NDArray, float]] = {}
    for g in _CUBE:
        r = ft @ g @ fp.T
        r, t = _descend(points, template, r, ctm - r @ cp, cap, iterations)
        d2 = _squared_distances(points, r, t, template)
        rows, cols = linear_sum_assignment(np.minimum(d2, cap))
        # Unmatched points cost as much as an outlier, so larger matches are preferred.
        score = float(np.minimum(d2[rows, cols], cap).sum() + cap * (k - rows.size))
        assign = np.full(k, -1, dtype=np.int64)
        ok = d2[rows, cols] < cap
        assign[rows[ok]] = cols[ok]
        rms = float(np.sqrt(d2[rows[ok], cols[ok]].mean())) if ok.any() else np.inf
        key = tuple(assign)
        if key not in results or score < results[key][0]:
            results[key] = (score, assign, rms)
    ranked = sorted(results.values(), key=lambda v: v[0])
    return [(assign, rms) for _, assign, rms in ranked]


def classical_mds(distance: NDArray, dims: int = 3) -> NDArray[np.float64]:
    """Points whose pairwise distances best match ``distance`` (classical MDS), up to a
    rigid motion and a reflection.

    References
    ----------
    Torgerson 1952 (double centring of the squared distances, top eigenvectors).

    Examples
    --------
    >>> import numpy as np
    >>> square = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    >>> d = np.linalg.norm(square[:, None] - square[None], axis=2)
    >>> e = classical_mds(d)
    >>> bool(np.allclose(np.linalg.norm(e[:, None] - e[None], axis=2), d))
    True
    """
    k = distance.shape[0]
    j = np.eye(k) - 1.0 / k
    b = -0.5 * j @ (distance**2) @ j
    vals, vecs = np.linalg.eigh(b)
    top = np.argsort(vals)[::-1][:dims]
    return vecs[:, top] * np.sqrt(np.maximum(vals[top], 0.0))


def _cycle_changes(w: NDArray, d: NDArray, pair: NDArray, tpp: NDArray) -> NDArray:
    """Cost change of every 3-cycle of names (a takes b's, b takes c's, c takes a's) for
    the cost of :func:`refine_by_swaps`: ``pair[i, j]``, track i's change were it named
    as track j, less its term with j (counted twice), is summed round the cycle; the
    three terms inside it follow from ``tpp``, the template distances between the
    current names. (k, k, k), +inf where indices repeat."""
    ab, bc, ac = (slice(None), slice(None), None), (None, slice(None)), (slice(None), None)
    out = np.add(pair[ab], pair[bc])
    out += pair.T[ac]
    x, y, w2, d2 = np.empty_like(out), np.empty_like(out), 2.0 * w, 2.0 * d
    for ij, new, old in ((ac, ab, bc), (ab, bc, ac), (bc, ac, ab)):
        # pair ij's template distance tpp[new] for tpp[old]: w (d-new)² - w (d-old)², twice
        np.subtract(tpp[old], tpp[new], out=x)
        np.subtract(d2[ij], tpp[old], out=y)
        y -= tpp[new]
        x *= y
        x *= w2[ij]
        out += x
    i = np.arange(w.shape[0])
    out[i, i], out[:, i, i], out[i, :, i] = np.inf, np.inf, np.inf
    return out


def _best_moves(
    d: NDArray,
    w: NDArray,
    template_distance: NDArray,
    p: NDArray,
    on: NDArray,
    unary: NDArray | None = None,
    price: float | None = None,
) -> tuple[tuple[float, ...], tuple[tuple, ...]]:
    """Cost change of the best exchange, move to a free name and 3-cycle (and, with a
    ``price``, of leaving a named track out), and where; ``on``: tracks named."""
    q = np.where(on, p, 0)
    wm = w * on[None, :]  # pairs with a track left out cost nothing
    wd = wm * d
    # g[a, x] is track a's share of the cost were it named x.
    tp = template_distance[:, q]  # (n_names, k)
    g = (wd * d).sum(axis=1)[:, None] - 2.0 * wd @ tp.T + wm @ (tp.T**2)
    own = np.where(on, g[np.arange(q.size), q], 0.0)
    t_ab = template_distance[np.ix_(q, q)]
    keep_ab = w * ((d - t_ab) ** 2 - d**2)  # the a-b term, unchanged by the exchange
    # pair[a, b]: track a's change were it named as track b, less its a-b term.
    pair = 2.0 * (g[:, q] - own[:, None] + keep_ab)
    move = 2.0 * (g - own[:, None])
    own_u = np.zeros(q.size)
    if unary is not None:
        # unary[a, x]: track a's own cost of name x, added once per track.
        held = unary[:, q]  # held[a, b]: track a with track b's name
        own_u = np.where(on, np.diagonal(held), 0.0)
        pair += held - own_u[:, None]
        free = ~np.isin(np.arange(unary.shape[1]), q[on])
        move += np.where(free[None, :], unary - own_u[:, None], 0.0)
    swap = pair + pair.T
    np.fill_diagonal(swap, 0.0)
    move[:, q[on]] = 0.0  # names already held are exchanged, not taken
    cycle = _cycle_changes(w, d, pair, t_ab)
    changes = [swap, move, cycle]
    if price is not None:
        off = ~on
        swap[off], swap[:, off] = np.inf, np.inf
        cycle[off], cycle[:, off], cycle[:, :, off] = np.inf, np.inf, np.inf
        move[off] -= price  # a left-out track named
        move[:, q[on]] = 0.0
        out = price - leave_savings(np.where(on, p, -1), d, w, template_distance, unary)
        changes.append(np.where(on, out, np.inf))  # a named one left out
    at = tuple(np.unravel_index(np.argmin(m), m.shape) for m in changes)
    return tuple(m[a] for m, a in zip(changes, at, strict=True)), at


def refine_by_swaps(
    distance: NDArray,
    weight: NDArray,
    template_distance: NDArray,
    assign: NDArray,
    unary: NDArray | None = None,
    price: float | None = None,
) -> NDArray[np.int64]:
    """Improve a track -> template assignment by exchanging labels (2-opt local search).

    Minimises ``sum_ij weight_ij (distance_ij - template_distance[a_i, a_j])²``: pairs of
    tracks whose distance barely varies (markers on one segment) weigh most, so the foot
    and shank markers, whose arrangement an average pose blurs, are put right. Tracks with
    ``assign < 0`` are left out; a track may also move to a name no track holds. Each step
    takes the steepest of all single exchanges, moves to a free name and 3-cycles of
    names, their cost changes computed at once. ``unary`` (tracks x names), when given,
    adds each track's own cost of its name (e.g. how far its height is from the name's).
    With a ``price``, each track left out costs it, and a step may also leave a named
    track out or name a left-out one (a marker of no name of the set need not take one).

    References
    ----------
    Croes 1958 (the 2-opt exchange search).
    """
    assign = assign.copy()
    rows = np.flatnonzero(assign >= 0) if price is None else np.arange(assign.size)
    if np.sum(assign >= 0) < 3:
        return assign
    d = np.nan_to_num(distance[np.ix_(rows, rows)])
    w = np.nan_to_num(weight[np.ix_(rows, rows)])
    p = assign[rows].copy()
    on = p >= 0
    u = None if unary is None else unary[rows]
    for _ in range(20 * p.size):  # passes at most
        gains, at = _best_moves(d, w, template_distance, p, on, u, price)
        if min(gains) > -1e-9:
            break
        kind = int(np.argmin(gains))
        if kind == 0:
            a, b = at[0]
            p[a], p[b] = p[b], p[a]
        elif kind == 1:
            am, x = at[1]
            p[am], on[am] = x, True
        elif kind == 2:
            ca, cb, cc = at[2]
            p[ca], p[cb], p[cc] = p[cb], p[cc], p[ca]
        else:
            on[at[3][0]] = False
    assign[rows] = np.where(on, p, -1)
    return assign


def refine_with_kicks(
    distance: NDArray,
    weight: NDArray,
    template_distance: NDArray,
    assign: NDArray,
    unary: NDArray | None = None,
    price: float | None = None,
) -> NDArray[np.int64]:
    """:func:`refine_by_swaps`, then iterated local search: exchange the names of four
    random named tracks at a time (a kick out of the valley) and descend again; keep
    the best. When names are free (fewer tracks than names), as many kicks again give
    four tracks names drawn from theirs and the free ones; with a ``price`` (a track
    may be left out), only these, and none is a name too. Deterministic (a fixed seed).

    The exchange search only descends, and a walking trial's average pose blurs the
    feet so much that an assignment with three foot markers wrong in one exchange each
    can be a local minimum twenty times the true one's cost; and a foot whose ankle is
    hidden, named as the shank's pair, only reaches its own names when both move.

    References
    ----------
    Lourenço, Martin & Stützle 2003 (iterated local search).
    """
    rng = np.random.default_rng(0)
    kicks = 60  # exchanges of four named tracks; as many again with free names

    def descend(trial: NDArray) -> tuple[NDArray, float]:
        out = refine_by_swaps(distance, weight, template_distance, trial, unary, price)
        return out, swap_cost(out, distance, weight, template_distance, unary, price)

    best, best_cost = descend(assign)
    named = np.flatnonzero(best >= 0)
    if named.size < 5:
        return best
    n_names = template_distance.shape[0]
    free_rng = np.random.default_rng([0, 1])
    has_free = n_names > named.size or price is not None
    # With a price, the exchanges of named tracks were tried before (without it).
    for kick in range(kicks if price is not None else 0, kicks * (2 if has_free else 1)):
        trial = best.copy()
        named = np.flatnonzero(best >= 0)
        if kick < kicks:
            idx = rng.choice(named, 4, replace=False)
            trial[idx] = trial[rng.permutation(idx)]
        elif price is None:
            # Names no track holds enter too: a segment named as its neighbour (a foot
            # as the shank's pair) moves to the free names only all at once.
            idx = free_rng.choice(named, 4, replace=False)
            pool = np.union1d(trial[idx], np.setdiff1d(np.arange(n_names), trial[named]))
            trial[idx] = free_rng.choice(pool, 4, replace=False)
        else:  # and leaving a track out, or naming one left out
            idx = free_rng.choice(best.size, 4, replace=False)
            pool = np.setdiff1d(np.arange(n_names), np.delete(trial, idx))
            trial[idx] = free_rng.choice(np.r_[pool, [-1] * 4], 4, replace=False)
        trial, cost = descend(trial)
        if cost < best_cost - 1e-9:
            best, best_cost = trial, cost
    return best


def swap_cost(
    assign: NDArray,
    distance: NDArray,
    weight: NDArray,
    template_distance: NDArray,
    unary: NDArray | None = None,
    price: float | None = None,
) -> float:
    """The cost :func:`refine_by_swaps` minimises, of one assignment (``-1``: left out,
    at ``price`` each when given)."""
    ok = assign >= 0
    names = assign[ok]
    diff = np.nan_to_num(distance[np.ix_(ok, ok)]) - template_distance[np.ix_(names, names)]
    cost = float((np.nan_to_num(weight[np.ix_(ok, ok)]) * diff**2).sum())
    if unary is not None:
        cost += float(unary[np.flatnonzero(ok), names].sum())
    return cost + (price or 0.0) * float((~ok).sum())


def leave_savings(
    assign: NDArray,
    distance: NDArray,
    weight: NDArray,
    template_distance: NDArray,
    unary: NDArray | None = None,
) -> NDArray[np.float64]:
    """What leaving each named track of ``assign`` out saves of :func:`swap_cost` (its
    terms with the other named tracks, counted twice, and its own unary cost); 0 for
    the tracks left out."""
    on = assign >= 0
    q = np.where(on, assign, 0)
    w = np.nan_to_num(weight) * (on[:, None] & on[None, :])
    out = 2.0 * (w * (np.nan_to_num(distance) - template_distance[np.ix_(q, q)]) ** 2).sum(1)
    if unary is not None:
        out += unary[np.arange(q.size), q]
    return np.where(on, out, 0.0)


def field_fits(
    dense: NDArray, fields: NDArray, rows: NDArray, cols: NDArray, template: NDArray
) -> NDArray[np.float64]:
    """RMS distance per field of a proper rigid fit of tracks ``rows`` to template ``cols``.

    ``dense`` is (tracks, fields, 3) with NaN where a track is not seen; fields where
    fewer than three of the tracks are seen are left out.
    """
    return _field_kabsch(dense, fields, rows, cols, template)[1]


def _field_kabsch(
    dense: NDArray, fields: NDArray, rows: NDArray, cols: NDArray, template: NDArray
) -> tuple[NDArray, NDArray]:
    """Per field of ``fields`` where three or more of tracks ``rows`` are seen, the proper
    rigid fit of their points onto the template's ``cols`` points (Kabsch 1976, all
    fields at once): rotations (m, 3, 3) and fit RMS (m,)."""
    src = np.transpose(dense[rows][:, fields], (1, 0, 2))  # (fields, k, 3)
    ok = np.isfinite(src[..., :1])
    keep = ok.sum(axis=(1, 2)) >= 3
    ok, n = ok[keep], ok[keep].sum(axis=1)
    src = np.where(ok, src[keep], 0.0)
    dst = np.where(ok, template[cols][None], 0.0)
    cs, ct = src.sum(axis=1) / n, dst.sum(axis=1) / n
    h = np.einsum("fki,fkj->fij", np.where(ok, src - cs[:, None], 0.0), dst - ct[:, None])
    u, _, vt = np.linalg.svd(h)
    v, ut = np.transpose(vt, (0, 2, 1)), np.transpose(u, (0, 2, 1))
    sign = np.sign(np.linalg.det(v @ ut))
    v[:, :, 2] *= np.where(sign == 0, 1.0, sign)[:, None]
    r = v @ ut
    fit = src @ np.transpose(r, (0, 2, 1)) + (ct - np.einsum("fij,fj->fi", r, cs))[:, None]
    return r, np.sqrt(np.sum(np.where(ok, fit - dst, 0.0) ** 2, axis=(1, 2)) / n[:, 0])


def upright_fraction(
    dense: NDArray, fields: NDArray, rows: NDArray, cols: NDArray, template: NDArray
) -> float:
    """Fraction of ``fields`` in which the proper rigid fit of tracks ``rows`` to template
    ``cols`` keeps the vertical within 45 degrees (both frames Z up)."""
    r = _field_kabsch(dense, fields, rows, cols, template)[0]
    return float(np.mean(r[:, 2, 2] > np.cos(np.pi / 4))) if len(r) else 0.0


def upright_pose(pose: NDArray, heights: NDArray) -> NDArray[np.float64]:
    """``pose`` (k, 3), e.g. from :func:`classical_mds`, turned so that its third axis is
    the direction along which it best explains ``heights`` (k,) by least squares."""
    centred = pose - pose.mean(axis=0)
    up, *_ = np.linalg.lstsq(centred, heights - heights.mean(), rcond=None)
    norm = np.linalg.norm(up)
    if not norm > 0:
        return centred
    up = up / norm
    helper = np.eye(3)[int(np.argmin(np.abs(up)))]
    e1 = np.cross(helper, up)
    e1 /= np.linalg.norm(e1)
    basis = np.column_stack([e1, np.cross(up, e1), up])
    return centred @ basis


def mirror_permutation(template: NDArray, tolerance_mm: float) -> NDArray[np.int64] | None:
    """The name each name becomes in the marker set's mirror image (RASI <-> LASI, SACR
    stays), or None when the set has no mirror symmetry within ``tolerance_mm`` / 4."""
    centred = template - template.mean(axis=0)
    assign, rms = match_to_template(-centred, centred, tolerance_mm)
    if (assign < 0).any() or not rms <= tolerance_mm / 4:
        return None
    return assign
