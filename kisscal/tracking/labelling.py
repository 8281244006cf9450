"""Automatic labelling of tracks with a marker set (beyond the seeds, which left it to the
operator).

Input: blended pieces and the ``[markers]`` set (names, a template of positions in a
standing pose in any coordinate frame, optional rigid segments). Nothing depends on where
the subject stands or faces:

1. Average pose: in a window where most long pieces are seen together, the median
   distance between every pair of pieces is taken (it averages out the swing of the
   legs) and turned into points by classical MDS; these are matched to the template by
   rigid fits (24 starts, Hungarian + Kabsch), refined by exchanging names to fit the
   distances that stay constant (markers on one segment), and of a correspondence and its
   left/right mirror image (equal in distances) the one that fits the real fields with a
   proper rotation is kept.
2. Spreading: other pieces take the free name (not held in their fields) whose rigid
   partners keep the template distance from them; repeated as names spread through time;
   windows where unnamed long pieces remain are matched again; groups of unnamed pieces
   that entered the view together (a whole foot) are named jointly.
3. Pieces sharing a name are joined. Short pieces that fit no name are ghosts and are
   dropped (Shafiq's clean-up); long ones are kept, named ``M<k>`` and reported. When too
   few names are matched (a stick, a thrown ball), all tracks are named M1, M2, ... .
"""

from __future__ import annotations

import itertools
import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from kisscal.errors import KisscalError
from kisscal.tracking.blending import bridge_residual_mm
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import MEASURED, Tracks, make_tracks, numbering


@dataclass(frozen=True)
class Labelling:
    """Result of :func:`label_tracks`.

    Attributes
    ----------
    tracks : Tracks
        Tracks after joining pieces with the same label, numbered 0..n-1.
    labels : tuple of str
        Label per track of ``tracks``.
    fits_marker_set : bool
        Whether the trial's tracks fit the marker set (else all labels are M1, M2, ...).
    unlabelled : tuple of int
        Tracks (of ``tracks``) that fit no name of the marker set.
    missing : tuple of str
        Names of the marker set that no track took.
    fit_rms_mm : float
        Median over the sampled fields of the rigid fit RMS distance to the template.
    """

    tracks: Tracks
    labels: tuple[str, ...]
    fits_marker_set: bool
    unlabelled: tuple[int, ...]
    missing: tuple[str, ...]
    fit_rms_mm: float


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
# Floor (mm) of the spread of a pair's distance in the swap search weights: about the
# noise of a distance between two measured markers.
_SPREAD_FLOOR_MM = 3.0
# Two labelled tracks are taken to be on one rigid segment when their distance varies by
# less than this (SD, mm) and matches the template's within _RIGID_MATCH_MM.
_RIGID_SPREAD_MM = 5.0
_RIGID_MATCH_MM = 15.0
# Passes over the unnamed pieces; each pass only retries pieces near newly named ones.
_MAX_SWEEPS = 200
# Windows matched to the template after the first, where unnamed long pieces remain.
_MAX_WINDOWS = 12
# Rigid matches of the average pose (per mirror image) from which the swap search starts.
_SWAP_STARTS = 24
# Largest number of joint name choices tried for a group of unnamed pieces.
_MAX_GROUP_CHOICES = 20000


def _principal_frame(points: NDArray) -> NDArray[np.float64]:
    _, vecs = np.linalg.eigh(np.cov(points.T))
    if np.linalg.det(vecs) < 0:
        vecs[:, 0] = -vecs[:, 0]
    return vecs


def kabsch(source: NDArray, target: NDArray) -> tuple[NDArray, NDArray]:
    """Proper rotation R and translation t minimising sum |R s + t - g|² (no reflection)."""
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
    """
    found = rigid_matches(points, template, outlier_mm, iterations)
    if not found:
        return np.full(points.shape[0], -1, dtype=np.int64), float("inf")
    return found[0]


def rigid_matches(
    points: NDArray, template: NDArray, outlier_mm: float, iterations: int = 10
) -> list[tuple[NDArray[np.int64], float]]:
    """Distinct rigid correspondences of ``points`` to ``template``, best first.

    Iterated Hungarian assignment and Kabsch fit, started from the 24 axis-aligned
    orientations of the two principal-axis frames; each start gives one local optimum.
    Returns (template index per point or -1, RMS distance of the matched points in mm).
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
        t = ctm - r @ cp
        prev = None
        for _ in range(iterations):
            moved = points @ r.T + t
            d2 = ((moved[:, None, :] - template[None, :, :]) ** 2).sum(axis=2)
            rows, cols = linear_sum_assignment(np.minimum(d2, cap))
            good = d2[rows, cols] < cap
            if good.sum() < 3:
                break
            key = tuple(cols[good]) + tuple(rows[good])
            if key == prev:
                break
            prev = key
            r, t = kabsch(points[rows[good]], template[cols[good]])
        moved = points @ r.T + t
        d2 = ((moved[:, None, :] - template[None, :, :]) ** 2).sum(axis=2)
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


def _rich_fields(present: NDArray) -> NDArray[np.int64]:
    """Fields where at least 80 % of the largest number of simultaneous tracks are seen."""
    count = present.sum(axis=0)
    return np.flatnonzero(count >= max(3, 0.8 * count.max()))


def _median_distances(dense: NDArray, tracks: NDArray, fields: NDArray) -> NDArray:
    """Median over ``fields`` of the distance between every pair of ``tracks`` (NaN-aware)."""
    pts = dense[np.ix_(tracks, fields)]  # (k, F, 3)
    d = np.linalg.norm(pts[:, None] - pts[None, :], axis=3)  # (k, k, F)
    return np.nanmedian(d, axis=2)


def classical_mds(distance: NDArray, dims: int = 3) -> NDArray[np.float64]:
    """Points whose pairwise distances best match ``distance`` (Torgerson's classical MDS),
    up to a rigid motion and a reflection."""
    k = distance.shape[0]
    j = np.eye(k) - 1.0 / k
    b = -0.5 * j @ (distance**2) @ j
    vals, vecs = np.linalg.eigh(b)
    top = np.argsort(vals)[::-1][:dims]
    return vecs[:, top] * np.sqrt(np.maximum(vals[top], 0.0))


def _distance_spread(dense: NDArray, tracks: NDArray, fields: NDArray) -> NDArray:
    """Standard deviation over ``fields`` of the distance between every pair of tracks."""
    pts = dense[np.ix_(tracks, fields)]
    d = np.linalg.norm(pts[:, None] - pts[None, :], axis=3)
    return np.nanstd(d, axis=2)


def _cycle_changes(w: NDArray, d: NDArray, gpp: NDArray, tpp: NDArray) -> NDArray:
    """Cost change of every 3-cycle of names (a takes b's, b takes c's, c takes a's) for
    the cost of :func:`refine_by_swaps`; ``gpp[i, j]`` is track i's share were it named as
    track j, ``tpp`` the template distances between the current names. (k, k, k), +inf
    where indices repeat."""
    k = w.shape[0]
    a, b, c = np.meshgrid(np.arange(k), np.arange(k), np.arange(k), indexing="ij")

    def term(i: NDArray, j: NDArray, t: NDArray) -> NDArray:
        return w[i, j] * (d[i, j] - t) ** 2

    # Each track's share with its new name, minus the part that pairs it with the other
    # two (counted with their old names in gpp), ...
    share = gpp[a, b] - gpp[a, a] + gpp[b, c] - gpp[b, b] + gpp[c, a] - gpp[c, c]
    inner = (
        term(a, b, tpp[b, b])
        - term(a, b, tpp[a, b])
        + term(a, c, tpp[b, c])
        - term(a, c, tpp[a, c])
        + term(b, a, tpp[c, a])
        - term(b, a, tpp[b, a])
        + term(b, c, tpp[c, c])
        - term(b, c, tpp[b, c])
        + term(c, a, tpp[a, a])
        - term(c, a, tpp[c, a])
        + term(c, b, tpp[a, b])
        - term(c, b, tpp[c, b])
    )
    # ... plus the exact change of the three pairs inside the cycle.
    within = 2.0 * (
        term(a, b, tpp[b, c])
        - term(a, b, tpp[a, b])
        + term(a, c, tpp[b, a])
        - term(a, c, tpp[a, c])
        + term(b, c, tpp[c, a])
        - term(b, c, tpp[b, c])
    )
    out = 2.0 * (share - inner) + within
    out[(a == b) | (b == c) | (a == c)] = np.inf
    return out


def refine_by_swaps(
    distance: NDArray,
    weight: NDArray,
    template_distance: NDArray,
    assign: NDArray,
    max_passes: int = 20,
) -> NDArray[np.int64]:
    """Improve a track -> template assignment by exchanging labels (2-opt local search).

    Minimises ``sum_ij weight_ij (distance_ij - template_distance[a_i, a_j])²``: pairs of
    tracks whose distance barely varies (markers on one segment) weigh most, so the foot
    and shank markers, whose arrangement an average pose blurs, are put right. Tracks with
    ``assign < 0`` are left out; a track may also move to a name no track holds.
    """
    assign = assign.copy()
    rows = np.flatnonzero(assign >= 0)
    if rows.size < 3:
        return assign
    d = np.nan_to_num(distance[np.ix_(rows, rows)])
    w = np.nan_to_num(weight[np.ix_(rows, rows)])
    p = assign[rows].copy()

    wd = w * d
    wdd = (wd * d).sum(axis=1)
    idx = np.arange(p.size)
    for _ in range(max_passes * p.size):
        # Steepest descent over all single exchanges, their cost changes computed at once:
        # g[a, x] is track a's share of the cost were it named x.
        tp = template_distance[:, p]  # (n_names, k)
        g = wdd[:, None] - 2.0 * wd @ tp.T + w @ (tp.T**2)
        own = g[idx, p]
        t_ab = template_distance[np.ix_(p, p)]
        keep_ab = w * ((d - t_ab) ** 2 - d**2)  # the a-b term, unchanged by the exchange
        swap = 2.0 * (g[:, p] - own[:, None] + g[:, p].T - own[None, :] + 2.0 * keep_ab)
        np.fill_diagonal(swap, 0.0)
        move = 2.0 * (g - own[:, None])
        move[:, p] = 0.0  # names already held are exchanged, not taken
        cycle = _cycle_changes(w, d, g[:, p], t_ab)
        a, b = np.unravel_index(np.argmin(swap), swap.shape)
        am, x = np.unravel_index(np.argmin(move), move.shape)
        ca, cb, cc = np.unravel_index(np.argmin(cycle), cycle.shape)
        gains = (swap[a, b], move[am, x], cycle[ca, cb, cc])
        if min(gains) > -1e-9:
            break
        kind = int(np.argmin(gains))
        if kind == 0:
            p[a], p[b] = p[b], p[a]
        elif kind == 1:
            p[am] = x
        else:
            p[ca], p[cb], p[cc] = p[cb], p[cc], p[ca]
    assign[rows] = p
    return assign


def _field_fits(
    dense: NDArray, fields: NDArray, rows: NDArray, cols: NDArray, template: NDArray
) -> NDArray[np.float64]:
    """RMS distance per field of a proper rigid fit of tracks ``rows`` to template ``cols``."""
    out = []
    for f in fields:
        ok = np.isfinite(dense[rows, f, 0])
        if ok.sum() < 3:
            continue
        src = dense[rows[ok], f]
        dst = template[cols[ok]]
        r, t = kabsch(src, dst)
        out.append(np.sqrt(np.mean(np.sum((src @ r.T + t - dst) ** 2, axis=1))))
    return np.asarray(out)


def _mirror_permutation(template: NDArray, tolerance_mm: float) -> NDArray[np.int64] | None:
    """The name each name becomes in the marker set's mirror image (RASI <-> LASI, SACR
    stays), or None when the set has no mirror symmetry within ``tolerance_mm`` / 4."""
    centred = template - template.mean(axis=0)
    assign, rms = match_to_template(-centred, centred, tolerance_mm)
    if (assign < 0).any() or not rms <= tolerance_mm / 4:
        return None
    return assign


def _generic(tracks: Tracks, params: TrackingParams, names: tuple, fit_rms: float) -> Labelling:
    """No marker set fits: clean up short tracks and name the rest M1, M2, ..."""
    tracks = tracks.select(tracks.n_status(MEASURED)[tracks.track] >= params.min_track_length)
    generic = tuple(f"M{i + 1}" for i in range(tracks.n_tracks))
    return Labelling(tracks, generic, False, (), names, fit_rms)


def _rigid_pairs(
    name_pos: NDArray,
    fields: NDArray,
    template_distance: NDArray,
    names: tuple[str, ...],
    segments: list | tuple | None,
) -> NDArray[np.bool_]:
    """Name pairs on one rigid segment: given ``segments``, plus named trajectories whose
    distance barely varies over ``fields`` and equals the template's."""
    n = len(names)
    rigid = np.zeros((n, n), dtype=bool)
    index = {name: i for i, name in enumerate(names)}
    for pair in segments or ():
        if len(pair) == 2 and pair[0] in index and pair[1] in index:
            rigid[index[pair[0]], index[pair[1]]] = rigid[index[pair[1]], index[pair[0]]] = True
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # pairs never seen together
        spread = _distance_spread(name_pos, np.arange(n), fields)
        median = _median_distances(name_pos, np.arange(n), fields)
        ok = (spread < _RIGID_SPREAD_MM) & (np.abs(median - template_distance) < _RIGID_MATCH_MM)
    np.fill_diagonal(ok, False)
    return rigid | ok


def _by_segments(
    piece_fields: NDArray,
    piece_xyz: NDArray,
    free: NDArray,
    name_pos: NDArray,
    rigid: NDArray,
    template_distance: NDArray,
    params: TrackingParams,
) -> tuple[int, NDArray[np.int64], NDArray[np.int64]]:
    """Free name whose rigid partners keep their template distance from a piece.

    Partners are the name pairs known to be rigid: given segments, or found rigid among
    the trajectories named from the average pose.

    Returns the name pinned by two or more partners (-1 if none), the free names that one
    partner allows, and those without any partner in view.
    """
    d = np.linalg.norm(name_pos[:, piece_fields] - piece_xyz[None], axis=2)  # (n, F)
    seen = np.isfinite(d)
    used = rigid[free] & seen.any(axis=1)[None, :]  # (J, n)
    # Short pieces are mostly ghosts: ask them for a closer fit.
    short = piece_fields.size < params.min_track_length
    tolerance = params.label_segment_tolerance_mm * (0.5 if short else 1.0)
    residual2 = (np.nan_to_num(d)[None, :, :] - template_distance[free][:, :, None]) ** 2
    weight = used[:, :, None] & seen[None, :, :]
    count = weight.sum(axis=(1, 2))
    rms = np.sqrt(np.where(weight, residual2, 0.0).sum(axis=(1, 2)) / np.maximum(count, 1))
    n_used = used.sum(axis=1)
    fits = (n_used > 0) & (rms <= tolerance)
    # One partner leaves the piece anywhere on a sphere around it, which a ghost near the
    # body may touch by chance; two pin it to a circle, enough for a piece that moves
    # along it for a few fields; a point or two needs three when the name has three.
    n_partners = rigid[free].sum(axis=1)
    pinned = fits & (n_used >= np.minimum(3 if piece_fields.size < 3 else 2, n_partners))
    pinned &= n_used >= 2
    best = int(free[np.argmin(np.where(pinned, rms, np.inf))]) if pinned.any() else -1
    return best, free[fits & (n_used == 1)], free[n_used == 0]


def _by_body_fit(
    piece_fields: NDArray,
    piece_xyz: NDArray,
    free: NDArray,
    name_pos: NDArray,
    template: NDArray,
    params: TrackingParams,
    prefer: NDArray | None = None,
) -> int:
    """Free name whose expected position, seen from its nearest named neighbours, the
    piece keeps closest to, if clearly closer than any other free name.

    At each of up to 9 fields of the piece the body's orientation R comes from a rigid fit
    of every named marker to the template; name j is then expected at
    P_k + R^T (T_j - T_k) from each of its four template-nearest named neighbours k
    (local, so that bent joints far away do not matter). The median distance over the
    fields decides; the best must be within ``label_tolerance_mm`` and the runner-up at
    least 1.5 times farther. A single name in ``prefer`` (confirmed by one rigid partner)
    is taken when within ``label_tolerance_mm`` and no other is 1.5 times closer.
    """
    pick = np.linspace(0, piece_fields.size - 1, min(9, piece_fields.size)).round().astype(int)
    dist = np.full((pick.size, free.size), np.nan)
    for i, row in enumerate(pick):
        f = piece_fields[row]
        held = np.flatnonzero(np.isfinite(name_pos[:, f, 0]))
        if held.size < 3:
            continue
        r, _ = kabsch(name_pos[held, f], template[held])
        gap = np.linalg.norm(template[free][:, None] - template[held][None], axis=2)
        near = held[np.argsort(gap, axis=1)[:, :4]]  # (J, 4) nearest named neighbours
        expect = name_pos[near, f] + (template[free][:, None, :] - template[near]) @ r
        dist[i] = np.linalg.norm(piece_xyz[row] - expect.mean(axis=1), axis=1)
    if np.isnan(dist).all():
        return -1
    score = np.nanmedian(dist, axis=0)
    order = np.argsort(score)
    best = score[order[0]]
    second = score[order[1]] if order.size > 1 else np.inf
    if best <= params.label_tolerance_mm and second >= 1.5 * best:
        return int(free[order[0]])
    if free.size == 1 and best <= 2.0 * params.label_tolerance_mm:
        # The only name the rigid partners leave: the body fit need only roughly agree
        # (the other side's marker of the pair would lie farther still).
        return int(free[0])
    if prefer is not None and prefer.size == 1:
        # The one name a rigid partner confirms wins unless the body clearly disagrees.
        k = int(np.flatnonzero(free == prefer[0])[0])
        others = np.delete(score, k)
        if score[k] <= params.label_tolerance_mm and not (others < score[k] / 1.5).any():
            return int(prefer[0])
    return -1


def _continues(track_pos: NDArray, fields: NDArray, xyz: NDArray, params: TrackingParams) -> bool:
    """Whether a piece continues a named trajectory smoothly where they are close in time.

    The trajectory's samples up to ``max_fill_gap_fields + 1`` fields before and after
    the piece and the piece itself must fit one polynomial (cubic, or lower with few
    points) within ``split_tolerance_mm`` RMS; with no such samples the piece passes.
    """
    reach = params.max_fill_gap_fields + 1
    near = np.r_[
        np.arange(fields[0] - reach, fields[0]), np.arange(fields[-1] + 1, fields[-1] + reach + 1)
    ]
    near = near[(near >= 0) & (near < track_pos.shape[0])]
    near = near[np.isfinite(track_pos[near, 0])]
    if near.size < 2:
        return True
    residual = bridge_residual_mm(near, track_pos[near], fields, xyz)
    return not residual > params.split_tolerance_mm


def _unnamed_groups(
    tracks: Tracks,
    label_of: NDArray,
    n_measured: NDArray,
    start: NDArray,
    stop: NDArray,
    params: TrackingParams,
) -> list[NDArray[np.int64]]:
    """Groups of 2 to 4 unnamed pieces of at least ``min_body_fit_points`` points, each
    sharing at least three fields with another of its group."""
    cand = np.flatnonzero((label_of < 0) & (n_measured >= params.min_body_fit_points))
    if cand.size < 2:
        return []
    spans = [set(tracks.field[start[t] : stop[t]].tolist()) for t in cand]
    parent = list(range(cand.size))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for i in range(cand.size):
        for k in range(i + 1, cand.size):
            if len(spans[i] & spans[k]) >= 3:
                parent[root(k)] = root(i)
    groups: dict[int, list[int]] = {}
    for i in range(cand.size):
        groups.setdefault(root(i), []).append(int(cand[i]))
    return [np.asarray(g) for g in groups.values() if 2 <= len(g) <= 4]


def _name_group(
    pieces: list[tuple[NDArray, NDArray]],
    name_pos: NDArray,
    rigid: NDArray,
    template_distance: NDArray,
    template: NDArray,
    params: TrackingParams,
) -> NDArray[np.int64] | None:
    """Names for a group of unnamed pieces, chosen jointly by their rigid distances.

    Every one-to-one choice of free names is scored by the RMS difference between the
    template lengths and the distances of the pairs it makes rigid: among the pieces, and
    from each piece to named partners. Every piece must take part in at least one rigid
    pair, the best choice must fit within ``label_segment_tolerance_mm`` and be at least
    twice better than any choice that differs in more than a left/right mirror; between a
    choice and its mirror image the rigid fit of the body decides. Returns None when the
    group cannot be named safely.
    """
    free_sets = [
        set(np.flatnonzero(~np.isfinite(name_pos[:, f, 0]).any(axis=1)).tolist()) for f, _ in pieces
    ]
    # Distances among the pieces (median over shared fields) and to named markers.
    k = len(pieces)
    between = np.full((k, k), np.nan)
    for a in range(k):
        for b in range(a + 1, k):
            fa, xa = pieces[a]
            fb, xb = pieces[b]
            shared, ia, ib = np.intersect1d(fa, fb, return_indices=True)
            if shared.size >= 3:
                between[a, b] = between[b, a] = np.median(np.linalg.norm(xa[ia] - xb[ib], axis=1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # names never seen with a piece
        to_named = [
            np.nanmedian(np.linalg.norm(name_pos[:, f] - x[None], axis=2), axis=1)
            for f, x in pieces
        ]
    scored = []
    # A name stays a candidate for a piece only if its named rigid partners in view
    # agree with it.
    options_per_piece = []
    for i in range(k):
        keep = []
        for j in sorted(free_sets[i]):
            partners = np.flatnonzero(rigid[j] & np.isfinite(to_named[i]))
            miss = to_named[i][partners] - template_distance[j, partners]
            if partners.size == 0 or np.sqrt(np.mean(miss**2)) <= params.label_segment_tolerance_mm:
                keep.append(j)
        options_per_piece.append(keep)
    if np.prod([len(o) for o in options_per_piece], dtype=float) > _MAX_GROUP_CHOICES:
        return None
    for choice in itertools.product(*options_per_piece):
        if len(set(choice)) < k:
            continue
        residuals = []
        involved = np.zeros(k, dtype=bool)
        for a in range(k):
            for b in range(a + 1, k):
                if rigid[choice[a], choice[b]] and np.isfinite(between[a, b]):
                    residuals.append(between[a, b] - template_distance[choice[a], choice[b]])
                    involved[[a, b]] = True
            partners = np.flatnonzero(rigid[choice[a]] & np.isfinite(to_named[a]))
            for q in partners:
                residuals.append(to_named[a][q] - template_distance[choice[a], q])
                involved[a] = True
        if not involved.all():
            continue
        scored.append((float(np.sqrt(np.mean(np.square(residuals)))), choice))
    if not scored:
        return None
    scored.sort()
    best_rms, best = scored[0]
    if best_rms > params.label_segment_tolerance_mm:
        return None
    rivals = [c for r, c in scored[1:] if r < 2.0 * max(best_rms, 1.0)]
    if rivals:
        # Only the mirror image of the best names, or the same names in another order
        # (two pieces whose distance fits either way round) may rival it: the body's
        # rigid fit picks among those.
        mirror = _mirror_permutation(template, params.label_tolerance_mm)
        same = {frozenset(best)}
        if mirror is not None:
            same.add(frozenset(mirror[list(best)].tolist()))
        if any(frozenset(c) not in same for c in rivals):
            return None
        options = [best, *rivals]
        # Compare the vectors between the pieces, turned into the template's frame by the
        # body's orientation, with the template's: a heel and a toe swapped point the
        # wrong way whatever the joints do.
        fits = []
        for choice in options:
            d = []
            for a in range(k):
                for b in range(a + 1, k):
                    fa, xa = pieces[a]
                    fb, xb = pieces[b]
                    shared, ia, ib = np.intersect1d(fa, fb, return_indices=True)
                    for n_row in range(0, shared.size, max(1, shared.size // 5)):
                        f = shared[n_row]
                        held = np.flatnonzero(np.isfinite(name_pos[:, f, 0]))
                        if held.size < 3:
                            continue
                        r, _ = kabsch(name_pos[held, f], template[held])
                        seen = (xa[ia[n_row]] - xb[ib[n_row]]) @ r.T
                        d.append(np.linalg.norm(seen - (template[choice[a]] - template[choice[b]])))
            fits.append(np.median(d) if d else np.inf)
        order = np.argsort(fits)
        if not fits[order[1]] > 1.5 * fits[order[0]]:
            return None
        best = options[order[0]]
    return np.asarray(best, dtype=np.int64)


def _match_window(
    dense: NDArray,
    present: NDArray,
    centre: int,
    window: int,
    template: NDArray,
    template_distance: NDArray,
    mirror_of: NDArray | None,
    params: TrackingParams,
    given_rigid: NDArray | None = None,
) -> tuple[NDArray | None, NDArray, float, NDArray]:
    """Names for the long tracks seen through most of a window of fields.

    Core: long tracks seen in most rich fields of the window. Their median pairwise
    distances describe an average pose; classical MDS turns it into points (up to a
    rigid motion and a mirror image) that are matched to the standing template, the
    correspondence is improved by :func:`refine_by_swaps`, and of it and its mirror image
    the one that fits the real fields with a proper rotation is kept. The median
    averages out the swing of the legs, which a single field's rigid fit cannot.

    With ``given_rigid`` (the session's segments as a name x name mask), two core tracks
    named as a rigid pair must keep the template's distance; tracks that break it are
    left unnamed here (the averaged pose of a leg half out of view can shift names along
    it), for the rigid-partner spreading to name later.

    Returns (core rows of ``dense`` or None, name per core row or -1, median fit RMS in
    mm, the rich fields used).
    """
    n_fields = present.shape[1]
    in_window = np.zeros(n_fields, dtype=bool)
    lo = min(max(centre - window // 2, 0), max(n_fields - window, 0))
    in_window[lo : lo + window] = True
    rich = _rich_fields(present & in_window[None, :])
    if rich.size > params.label_fields:
        rich = rich[np.linspace(0, rich.size - 1, params.label_fields).round().astype(int)]
    none = (None, np.empty(0, dtype=np.int64), float("nan"), rich)
    if rich.size == 0:  # never three tracks at once: no body to match
        return none
    core = np.flatnonzero(present[:, rich].mean(axis=1) >= 0.6)
    # Every pair of core tracks must share rich fields for a median distance; drop the
    # track missing most pairs until they all do (two pieces of one marker never meet).
    while core.size >= 3:
        seen = present[np.ix_(core, rich)].astype(int)
        never = ((seen @ seen.T) == 0).sum(axis=1)
        if never.max() == 0:
            break
        core = np.delete(core, int(np.argmax(never)))
    if core.size < 3:
        return none
    n_names = template.shape[0]
    median = _median_distances(dense, core, rich)
    weight = 1.0 / (_distance_spread(dense, core, rich) ** 2 + _SPREAD_FLOOR_MM**2)
    np.fill_diagonal(weight, 0.0)
    embedded = classical_mds(median)

    def swap_cost(q: NDArray) -> float:
        ok = q >= 0
        qq = q[ok]
        diff = median[np.ix_(ok, ok)] - template_distance[np.ix_(qq, qq)]
        return float((weight[np.ix_(ok, ok)] * diff**2).sum())

    refined = []
    for mirror in (1.0, -1.0):
        # Several rigid matches of the average pose serve as starts: the swap search
        # only descends, and one start can sit in a wrong valley.
        for assign, _ in rigid_matches(
            embedded * [1.0, 1.0, mirror], template, params.label_tolerance_mm
        )[:_SWAP_STARTS]:
            if (assign >= 0).sum() < 3:
                continue
            # Tracks too far from any name in the average pose still get a free name to
            # start from; the swap search then places them by their rigid partners.
            free = np.setdiff1d(np.arange(n_names), assign[assign >= 0])
            loose = np.flatnonzero(assign < 0)[: free.size]
            assign[loose] = free[: loose.size]
            assign = refine_by_swaps(median, weight, template_distance, assign)
            refined.append((swap_cost(assign), assign))
    if not refined:
        return none
    lowest = min(c for c, _ in refined)
    candidates = []
    seen_keys = set()
    for cost, assign in refined:
        # Only the distance-wise best (and equally good) correspondences go on to the
        # left/right test.
        if cost > lowest * 1.05 + 1e-9 or tuple(assign) in seen_keys:
            continue
        seen_keys.add(tuple(assign))
        # Distances cannot tell left from right: the mirror image of a correspondence
        # (left and right names exchanged) costs the same, so it is tried too.
        tries = [assign]
        if mirror_of is not None:
            tries.append(np.where(assign >= 0, mirror_of[np.maximum(assign, 0)], -1))
        for cand in tries:
            ok = cand >= 0
            rms = _field_fits(dense, rich, core[ok], cand[ok], template)
            candidates.append((float(np.median(rms)) if rms.size else np.inf, cand))
    if not candidates:
        return none
    fit_rms, assign = min(candidates, key=lambda c: c[0])
    if given_rigid is not None:
        # Two markers of one segment seen without their neighbours (a heel and a toe of a
        # foot whose ankle is hidden) can swap names at no cost in distances; the real
        # fields' rigid fit decides.
        for a, b in zip(*np.nonzero(np.triu(given_rigid[np.ix_(assign, assign)], 1)), strict=True):
            if assign[a] < 0 or assign[b] < 0:
                continue
            variant = assign.copy()
            variant[[a, b]] = assign[[b, a]]
            ok = variant >= 0
            rms = _field_fits(dense, rich, core[ok], variant[ok], template)
            if rms.size and np.median(rms) < 0.95 * fit_rms:
                fit_rms, assign = float(np.median(rms)), variant
        spread = _distance_spread(dense, core, rich)
        named = np.flatnonzero(assign >= 0)
        pa, pb = np.meshgrid(named, named, indexing="ij")
        pair = given_rigid[assign[pa], assign[pb]]
        broken = pair & (
            (np.abs(median[pa, pb] - template_distance[assign[pa], assign[pb]]) > _RIGID_MATCH_MM)
            | (spread[pa, pb] > _RIGID_SPREAD_MM)
        )
        assign = assign.copy()
        assign[named[broken.any(axis=1)]] = -1
    return core, assign, fit_rms, rich


def label_tracks(
    tracks: Tracks,
    names: tuple[str, ...] | list[str] | None,
    params: TrackingParams,
    template_mm: ArrayLike | None = None,
    segments: list[tuple[str, str]] | tuple | None = None,
) -> Labelling:
    """Name tracks from the marker set (DESIGN.md ``[markers]``).

    Parameters
    ----------
    tracks : Tracks
        Blended track pieces, short ones included: a short piece that fits a name joins
        that name's trajectory, one that fits none is dropped (Shafiq's clean-up of ghost
        tracks, ``min_track_length``); long pieces that fit none are reported.
    names : sequence of str or None
        Marker names. Without names or without a template, tracks are named M1, M2, ...
    params : TrackingParams
        ``label_tolerance_mm``, ``label_segment_tolerance_mm``, ``label_fields``,
        ``min_label_fraction``, ``min_label_points``, ``min_body_fit_points``.
    template_mm : (n, 3) array, optional
        Marker positions in a standing pose, same order as ``names``, any frame.
    segments : sequence of (str, str), optional
        Pairs of names on one rigid segment; added to the pairs found rigid in the data.

    Returns
    -------
    Labelling
    """
    if not names or template_mm is None or tracks.n_tracks == 0:
        return _generic(tracks, params, tuple(names or ()), float("nan"))
    names = tuple(names)
    template = np.asarray(template_mm, dtype=float)
    if template.shape != (len(names), 3):
        raise KisscalError(
            f"markers: template_mm needs one [x, y, z] per name ({len(names)}), "
            f"got shape {template.shape}"
        )
    if len(set(names)) != len(names):
        raise KisscalError("markers: names must be unique")
    n_names = len(names)
    n_measured = tracks.n_status(MEASURED)
    # Long tracks get a dense (track, field) table; the many short pieces (mostly ghosts)
    # are read from their own rows only.
    long_ids = np.flatnonzero(n_measured >= params.min_track_length)
    if long_ids.size < 3:
        return _generic(tracks, params, names, float("nan"))
    n_fields = int(tracks.field.max()) + 1
    rows = np.isin(tracks.track, long_ids)
    dense = np.full((long_ids.size, n_fields, 3), np.nan)
    dense[np.searchsorted(long_ids, tracks.track[rows]), tracks.field[rows]] = tracks.xyz_mm[rows]
    present = np.isfinite(dense[..., 0])
    template_distance = np.linalg.norm(template[:, None] - template[None, :], axis=2)
    mirror_of = _mirror_permutation(template, params.label_tolerance_mm)
    label_of = np.full(tracks.n_tracks, -1, dtype=np.int64)
    # The average pose is taken over a window of the trial where most long tracks are
    # seen together (in a long trial no piece spans the whole of it); names then spread
    # to the other pieces through their rigid partners, and windows where unnamed long
    # pieces remain are matched again.
    given_rigid = None
    if segments:
        given_rigid = _rigid_pairs(
            np.full((n_names, 1, 3), np.nan),
            np.zeros(1, dtype=np.int64),
            template_distance,
            names,
            segments,
        )
    window = min(params.label_window_fields, n_fields)
    box = np.ones(window)
    centre = int(np.argmax(np.convolve(present.sum(axis=0), box, mode="same")))
    core, assign, fit_rms, rich = _match_window(
        dense,
        present,
        centre,
        window,
        template,
        template_distance,
        mirror_of,
        params,
        given_rigid,
    )
    if core is None or not np.any(assign >= 0):
        return _generic(tracks, params, names, fit_rms)
    label_of[long_ids[core[assign >= 0]]] = assign[assign >= 0]

    start, stop = tracks.bounds()
    name_pos = np.full((n_names, n_fields, 3), np.nan)
    for t in np.flatnonzero(label_of >= 0):
        name_pos[label_of[t], tracks.field[start[t] : stop[t]]] = tracks.xyz_mm[start[t] : stop[t]]

    def name_piece(t: int, j: int) -> None:
        label_of[t] = j
        name_pos[j, tracks.field[start[t] : stop[t]]] = tracks.xyz_mm[start[t] : stop[t]]

    def propagate() -> None:
        # Other pieces, longest first: a name is free for a piece if no trajectory holds it
        # in the piece's fields; among free names the piece takes the one whose rigid
        # partners (on the same body segment) stay at the template's distance from it.
        # Naming one piece gives its neighbours a partner, so this repeats.
        rigid = _rigid_pairs(name_pos, rich, template_distance, names, segments)
        stamp = np.zeros(n_fields, dtype=np.int64)  # last pass that named something there
        for sweep in range(1, _MAX_SWEEPS + 1):
            changed = False
            waiting = np.flatnonzero((label_of < 0) & (n_measured >= params.min_label_points))
            for t in waiting[np.argsort(-n_measured[waiting], kind="stable")]:
                f_t = tracks.field[start[t] : stop[t]]
                if sweep > 1 and stamp[f_t].max() < sweep - 1:
                    continue  # nothing new around this piece since it was last tried
                xyz_t = tracks.xyz_mm[start[t] : stop[t]]
                free = np.flatnonzero(~np.isfinite(name_pos[:, f_t, 0]).any(axis=1))
                if free.size == 0:
                    continue
                j, one_partner, unknown = _by_segments(
                    f_t, xyz_t, free, name_pos, rigid, template_distance, params
                )
                undecided = np.r_[one_partner, unknown]
                if (
                    j < 0
                    and undecided.size == 1
                    and one_partner.size == 1
                    and n_measured[t] >= params.min_track_length
                ):
                    # Every other free name is ruled out by its rigid partners and one
                    # partner confirms this one: a long piece (not a ghost) takes it.
                    j = int(undecided[0])
                if j < 0 and undecided.size and n_measured[t] >= params.min_body_fit_points:
                    j = _by_body_fit(
                        f_t, xyz_t, undecided, name_pos, template, params, prefer=one_partner
                    )
                if j >= 0 and n_measured[t] < params.min_track_length:
                    # A short piece next to its name's trajectory must continue it: a ghost
                    # by a marker that just went out of sight need not.
                    if not _continues(name_pos[j], f_t, xyz_t, params):
                        j = -1
                if j >= 0:
                    name_piece(t, j)
                    stamp[f_t] = sweep
                    changed = True
            if not changed:
                break
            # Newly named pieces may show more rigid pairs (a name absent from the average
            # pose had none yet).
            rigid = _rigid_pairs(name_pos, rich, template_distance, names, segments)

    tried = np.zeros(n_fields, dtype=bool)
    for _ in range(_MAX_WINDOWS):
        propagate()
        unnamed = label_of[long_ids] < 0
        busy = np.convolve(present[unnamed].sum(axis=0), box, mode="same")
        busy[tried] = 0
        if not unnamed.any() or busy.max() < 3 * window * 0.5:
            break
        centre = int(np.argmax(busy))
        tried[max(centre - window // 2, 0) : centre + window // 2] = True
        core, assign, _, _ = _match_window(
            dense,
            present,
            centre,
            window,
            template,
            template_distance,
            mirror_of,
            params,
            given_rigid,
        )
        if core is None:
            continue
        for k, j in zip(core, assign, strict=True):
            t = long_ids[k]
            if j >= 0 and label_of[t] < 0 and not np.isfinite(name_pos[j, present[k], 0]).any():
                name_piece(t, int(j))
    # Pieces of one segment that entered the view together (a whole foot at the edge of
    # the volume) have no named partner to go by: name them jointly.
    rigid = _rigid_pairs(name_pos, rich, template_distance, names, segments)
    for group in _unnamed_groups(tracks, label_of, n_measured, start, stop, params):
        pieces = [
            (tracks.field[start[t] : stop[t]], tracks.xyz_mm[start[t] : stop[t]]) for t in group
        ]
        names_for = _name_group(pieces, name_pos, rigid, template_distance, template, params)
        if names_for is not None:
            for t, j in zip(group, names_for, strict=True):
                name_piece(int(t), int(j))
            propagate()
    # Short pieces that fit no name are ghosts (Shafiq's clean-up); long ones are reported.
    keep = (label_of >= 0) | (n_measured >= params.min_track_length)
    matched = np.unique(label_of[label_of >= 0])
    if matched.size < params.min_label_fraction * n_names:
        return _generic(tracks, params, names, fit_rms)

    # Join same-label pieces; unlabelled tracks keep their own group.
    group = np.where(label_of >= 0, label_of, n_names + np.arange(tracks.n_tracks))
    rows = keep[tracks.track]
    sample_group = group[tracks.track][rows]
    joined = make_tracks(
        tracks.field[rows],
        sample_group,
        tracks.xyz_mm[rows],
        tracks.corrected_mm[rows],
        tracks.status[rows],
        tracks.point[rows],
    )
    ids, rank, _ = numbering(tracks.field[rows], sample_group)
    new_group = np.empty(ids.size, dtype=np.int64)
    new_group[rank] = ids
    labels = []
    unlabelled = []
    for i, g in enumerate(new_group):
        if g < n_names:
            labels.append(names[g])
        else:
            unlabelled.append(i)
            labels.append(f"M{len(unlabelled)}")
    missing = tuple(n for j, n in enumerate(names) if j not in set(matched.tolist()))
    return Labelling(joined, tuple(labels), True, tuple(unlabelled), missing, fit_rms)
