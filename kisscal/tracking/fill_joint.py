"""Single-camera fill of a segment whose markers are all on rays: their depths together.

:mod:`kisscal.tracking.raychain` places a marker seen by one camera on its blob's ray at
the depth where its lengths to the segment's *measured* markers hold. In a lab of three
or four cameras a whole shank or foot often drops to one camera at once (the other leg
hides it): then no partner is measured, and neither that nor rigid-body fill can place
it. Each marker's blob is still there, so each marker has a ray and one unknown, its
depth along it; the segment's lengths (constant in the trial) between markers on rays,
and to any marker measured in that field, tie the depths together. With three markers
on rays and their three lengths the depths are fixed (the three-point pose problem of
one camera, up to a few discrete solutions; the one continuing the markers' paths is
taken).

Per field, the depths are solved by Gauss-Newton on every length whose SD in the trial
is at most ``rigid_fill_sd_mm`` (weighed by ``1 / SD²``, SD at least
``ray_length_sd_floor_mm``), started from the previous field's solution, walking the gap
from each side; a field is kept where both walks agree within
:data:`AGREE_MM`, every length agrees within three SDs, and the target's expected error
along its ray (from the solution's covariance) is at most ``ray_length_max_error_mm``.

References
----------
Haralick et al. 1994 (three-point perspective pose: a rigid triangle on three rays);
Hartley & Zisserman 2004 (rays of a projective camera); Challis 1995 (segments as rigid
bodies of markers).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import true_runs
from kisscal.dlt.model import ray_directions
from kisscal.tracking.blob_paths import chain_blobs
from kisscal.tracking.bodyfill import distance_sd
from kisscal.tracking.fill_donors import padded_mirrors, shared_blobs
from kisscal.tracking.on_rays import ChainFill, path_runs
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs
from kisscal.tracking.segment_lengths import length_partners

#: Largest distance (mm) between the solutions of the two walks for a field to be kept.
AGREE_MM = 5.0

#: Largest distance (mm) of the target from where its path, continued at constant
#: velocity from the last field placed, expects it.
STEP_MM = 20.0

#: Most Gauss-Newton iterations per field.
ITERS = 10
#: A depth step this small (mm) ends the length fit (Gauss-Newton steps shrink
#: quadratically: the next would move the depths by nanometres).
CONVERGED_MM = 1e-4


@dataclass(frozen=True)
class _Group:
    """The target (index 0) and its segment's markers, their lengths and SDs."""

    members: NDArray[np.int64]
    length: NDArray[np.float64]  # (m, m) mean distance over the trial
    sd: NDArray[np.float64]  # (m, m), inf where the pair is not rigid


def _group(
    dense: NDArray, t: int, params: TrackingParams, mirror: NDArray | None = None
) -> _Group | None:
    """Track ``t`` and its length partners (:func:`~.segment_lengths.length_partners`, with
    ``mirror``), and those measured with it too seldom to tell whose mirror images keep
    their length (:func:`_mirror_members`)."""
    own = length_partners(dense, t, params, mirror)[0]
    m = padded_mirrors(mirror, len(dense))
    extra = _mirror_members(dense, t, params, m)
    members = np.r_[t, own, extra].astype(np.int64)
    if members.size < 3:
        return None
    sd = distance_sd(dense[members], dense[members])
    dist = np.linalg.norm(dense[members][:, None] - dense[members][None], axis=3)
    seen = np.isfinite(dist)
    length = np.where(seen, dist, 0.0).sum(axis=2) / np.maximum(seen.sum(axis=2), 1)
    if extra.size and np.all(m[members] >= 0):
        # a pair with a member measured too seldom: its mirror pair's length, which the
        # two sides share within mirror_length_sd_mm (markers placed by hand)
        late = np.arange(members.size) > own.size
        pair = (late[:, None] | late[None]) & (seen.sum(axis=2) < params.body_context_fields)
        mine = dense[m[members]]
        md = np.linalg.norm(mine[:, None] - mine[None], axis=3)
        ms = np.isfinite(md)
        enough = ms.sum(axis=2) >= params.body_context_fields
        m_len = np.where(ms, md, 0.0).sum(axis=2) / np.maximum(ms.sum(axis=2), 1)
        m_sd = np.where(enough, distance_sd(mine, mine), np.inf)
        sd = np.where(pair, np.maximum(m_sd, params.mirror_length_sd_mm), sd)
        length = np.where(pair, m_len, length)
    sd = np.where(
        sd <= params.rigid_fill_sd_mm, np.maximum(sd, params.ray_length_sd_floor_mm), np.inf
    )
    np.fill_diagonal(sd, np.inf)
    return _Group(members, length, sd)


def _mirror_members(
    dense: NDArray, t: int, params: TrackingParams, m: NDArray[np.int64]
) -> NDArray[np.int64]:
    """Rows measured with track ``t`` in fewer than ``body_context_fields`` fields (too few
    to judge their length, :func:`~.segment_lengths.length_partners`) whose mirror image keeps
    within ``rigid_fill_sd_mm`` of ``t``'s mirror image's over at least as many: kiss 3
    seed 435's right ankle, one camera's all trial and measured in 10 fields, is the
    toe's third point where the toe's ray is square to the heel."""
    if m[t] < 0:
        return np.zeros(0, dtype=np.int64)
    seen = np.isfinite(dense[:, :, 0])
    few = (seen & seen[t]).sum(axis=1) < params.length_fields
    cand = np.flatnonzero(few & (m >= 0) & (np.arange(len(dense)) != t))
    both = (seen[m[cand]] & seen[m[t]]).sum(axis=1) >= params.body_context_fields
    sd = distance_sd(dense[m[cand]], dense[m[t]][None])[:, 0]
    return cand[both & (sd <= params.rigid_fill_sd_mm)]


def member_rays(
    dense: NDArray,
    u: int,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    params: TrackingParams,
    mirror: NDArray | None = None,
) -> NDArray[np.int64]:
    """Spare row of track ``u``'s own blob per camera and field of [lo, hi), shape
    (n_cameras, hi - lo) (-1 where none, or where ``u`` is measured), followed in the
    image across each of its unmeasured runs (from its one side at the trial's ends), but
    not one another track's image may share (:func:`.fill_donors.shared_blobs`)."""
    out = np.full((len(spare.dlts), hi - lo), -1, dtype=np.int64)
    series = dense[u]
    a_runs, b_runs = true_runs(~np.isfinite(series[:, 0]))
    partners = length_partners(dense, u, params, mirror)[0]
    for a, b in zip(a_runs.tolist(), b_runs.tolist(), strict=True):
        if b <= lo or a >= hi or (a == 0 and b == len(series)):
            continue
        ks, rows = chain_blobs(series, a, b, spare, params)
        k = ks + a - lo
        ok = (k >= 0) & (k < hi - lo)
        if partners.size:  # a blob another marker's image may share lies off u's ray
            ok &= ~shared_blobs(dense, u, a, ks, rows, spare, params, partners)
        out[spare.camera[rows[ok]], k[ok]] = rows[ok]
    return out


def pick_rays(cands: NDArray[np.int64]) -> NDArray[np.int64]:
    """One spare row per member and field from ``cands`` (m, n_cameras, n): the first
    camera's blob that no other member's path follows too, else the first camera's.
    Where two cameras see a marker and one of its blobs is shared (its image within a
    pixel or two of another marker's, which that camera lost or merged with it), that
    blob's ray passes both markers and fixes neither depth apart from the other; the
    marker's other blob is its own."""
    m = len(cands)
    same = cands[:, :, None, None, :] == cands[None, None, :, :, :]  # (m, c, m, c, n)
    same &= ~np.eye(m, dtype=bool)[:, None, :, None, None]
    valid = cands >= 0
    own = valid & ~same.any(axis=(2, 3))
    pick = np.where(own.any(axis=1), own.argmax(axis=1), valid.argmax(axis=1))  # (m, n)
    return np.take_along_axis(cands, pick[:, None, :], axis=1)[:, 0]


def _solve(
    centre: NDArray, d: NDArray, s0: NDArray, anchors: NDArray, grp_len: NDArray, grp_sd: NDArray
) -> tuple[NDArray, float, float]:
    """Depths ``s`` (r,) of r points on rays ``centre + s d`` from ``s0``, fitting the
    lengths among them and to ``anchors`` ((a, 3), fixed points); ``grp_len``/``grp_sd``
    are (r, r + a). Returns the depths, the largest length residual in SDs, and the
    expected error (mm) of the first depth (inf when not fixed)."""
    r = len(s0)
    i_idx, j_idx = np.nonzero(np.isfinite(grp_sd))
    i_idx, j_idx = i_idx[(j_idx >= r) | (j_idx > i_idx)], j_idx[(j_idx >= r) | (j_idx > i_idx)]
    if i_idx.size < r + 1:
        return s0, np.inf, np.inf  # no length to spare: a wrong blob would go unseen
    s = s0.astype(float).copy()
    done = False
    for it in range(ITERS + 1):
        x = centre + s[:, None] * d
        pts = np.concatenate([x, anchors])
        v = x[i_idx] - pts[j_idx]
        dist = np.maximum(np.linalg.norm(v, axis=1), 1e-9)
        w = 1.0 / grp_sd[i_idx, j_idx]
        res = (dist - grp_len[i_idx, j_idx]) * w
        jac = np.zeros((i_idx.size, r))
        u = v / dist[:, None]
        rows = np.arange(i_idx.size)
        jac[rows, i_idx] = np.einsum("ij,ij->i", u, d[i_idx]) * w
        inner = j_idx < r
        jac[rows[inner], j_idx[inner]] -= (
            np.einsum("ij,ij->i", u[inner], d[j_idx[inner]]) * w[inner]
        )
        info = jac.T @ jac
        if done or it == ITERS:
            break
        step = np.clip(np.linalg.lstsq(info, jac.T @ res, rcond=None)[0], -100.0, 100.0)
        s -= step
        # converged: what further steps would move is far below a micrometre
        done = bool(np.abs(step).max() < CONVERGED_MM)
    return fit_summary(s, res, info)


def fit_summary(x: NDArray, res: NDArray, info: NDArray) -> tuple[NDArray, float, float]:
    """A Gauss-Newton length fit's unknowns ``x``, its largest residual (in SDs, of
    ``res``) and the expected error of the first unknown from the information matrix
    ``info`` (inf when the lengths do not fix it)."""
    if np.linalg.cond(info) > 1e8:
        return x, float(np.abs(res).max()), np.inf
    return x, float(np.abs(res).max()), float(np.sqrt(np.linalg.inv(info)[0, 0]))


def _best_start(
    c: NDArray,
    d: NDArray,
    last: NDArray,
    idx: NDArray,
    anc: NDArray,
    grp: _Group,
    anchors: NDArray,
    stale: NDArray,
) -> tuple[NDArray, float, float]:
    """:func:`_solve` from the members' last positions, a member whose last position is
    not of the field before started from either place where its ray meets the sphere of
    its length about the target's last position; the start of smallest residual."""
    s0 = np.einsum("ij,ij->i", last[idx] - c, d)
    rel = last[idx[0]] - c
    b = np.einsum("ij,ij->i", rel, d)
    root = np.sqrt(np.maximum(grp.length[idx[0], idx] ** 2 - (np.sum(rel**2, axis=1) - b**2), 0))
    choices = [
        (b[i] - root[i], b[i] + root[i]) if stale[m] and i > 0 else (s0[i],)
        for i, m in enumerate(idx.tolist())
    ]
    cols = np.r_[idx, anc]
    length, sd = grp.length[np.ix_(idx, cols)], grp.sd[np.ix_(idx, cols)]
    best = (s0, np.inf, np.inf)
    for start in itertools.product(*choices):
        got = _solve(c, d, np.array(start), anchors, length, sd)
        if got[1] < best[1]:
            best = got
    return best


def edge_positions(series: NDArray, lo: int, hi: int, forward: bool) -> NDArray:
    """Each of ``series`` (m, n_fields, 3) at its last known field before ``lo``
    (``forward``) or its first after ``hi - 1`` (NaN where none)."""
    ok = np.isfinite(series[:, :, 0])
    out = np.full((len(series), 3), np.nan)
    for i in range(len(series)):
        f = np.flatnonzero(ok[i, :lo])[-1:] if forward else hi + np.flatnonzero(ok[i, hi:])[:1]
        if f.size:
            out[i] = series[i, f[0]]
    return out


def _walk(
    dense: NDArray, grp: _Group, rays: NDArray, lo: int, hi: int, spare: SpareBlobs, forward: bool
) -> tuple[NDArray, NDArray]:
    """Target position and expected error per field of [lo, hi), solved field by field
    from one side of the gap (NaN where not solved)."""
    n = hi - lo
    xyz, err = np.full((n, 3), np.nan), np.full(n, np.nan)
    members = grp.members
    last = edge_positions(dense[members], lo, hi, forward)  # (m, 3), NaN where none
    edge, step = (lo - 1, -1) if forward else (hi, 1)
    stale = ~np.isfinite(dense[members, edge, 0])
    # a member never known on this side (a heel whose track starts after the gap) is
    # stale: it starts on the sphere of its length about the target (_best_start)
    last = np.where(np.isfinite(last), last, last[:1])
    vel = np.nan_to_num(dense[members[0], edge] - dense[members[0], edge + step])
    since = 0
    for k in range(n) if forward else range(n - 1, -1, -1):
        f = lo + k
        since += 1  # fields since the last one placed, with a ray or not
        known = np.isfinite(dense[members, f, 0])
        on = (rays[:, k] >= 0) & ~known
        row = rays[:, k]
        if not on[0] or np.any(on[1:] & (row[1:] == row[0])):
            continue  # the target has no ray, or another marker follows its blob
        idx = np.flatnonzero(on)
        anc = np.flatnonzero(known)
        row = rays[idx, k]
        cam = spare.camera[row]
        d = ray_directions(spare.dlts[cam], spare.uv_px[row])
        c = spare.centres[cam]
        s, worst, e = _best_start(c, d, last, idx, anc, grp, dense[members[anc], f], stale)
        x = c + s[:, None] * d
        if worst <= 3.0 and np.linalg.norm(x[0] - last[0] - since * vel) <= STEP_MM:
            xyz[k], err[k] = x[0], e
            vel, since = (x[0] - last[0]) / since, 0
            last[idx], stale[idx] = x, False
        last[anc], stale[anc] = dense[members[anc], f], False
    return xyz, err


def joint_walks(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    params: TrackingParams,
    absent: NDArray | None = None,
    mirror: NDArray | None = None,
) -> tuple[_Group, NDArray, NDArray, NDArray, NDArray, NDArray] | None:
    """The two walks of :func:`joint_ray_fill` over the gap [lo, hi) of track ``t``: its
    segment, the members' spare rows per field (m, hi - lo), and each walk's target
    position (hi - lo, 3) and expected error (hi - lo,), NaN where not solved; None
    when the gap has no sides, the segment too few tracks, or the target no ray. The
    segment's members are tracks (rows of ``dense``) and markers no track took (rows of
    ``absent``, numbered on after the tracks:
    :func:`~kisscal.tracking.fill_absent.absent_placed`); ``mirror``: each row's mirror
    image's row (:func:`~.segment_lengths.length_partners`)."""
    if absent is not None:
        dense = np.concatenate([dense, absent])
    if lo < 2 or hi + 1 >= dense.shape[1] or not np.all(np.isfinite(dense[t, [lo - 1, hi]])):
        return None
    grp = _group(dense, t, params, mirror)
    if grp is None:
        return None
    rays = pick_rays(
        np.stack([member_rays(dense, int(u), lo, hi, spare, params, mirror) for u in grp.members])
    )
    if not np.any(rays[0] >= 0):
        return None
    fwd, e_f = _walk(dense, grp, rays, lo, hi, spare, True)
    bwd, e_b = _walk(dense, grp, rays, lo, hi, spare, False)
    return grp, rays, fwd, e_f, bwd, e_b


def joint_ray_fill(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    params: TrackingParams,
    absent: NDArray | None = None,
    mirror: NDArray | None = None,
) -> ChainFill | None:
    """Place fields of the gap [lo, hi) of track ``t`` on its own blob's rays together
    with the other markers of its segment on theirs (see module), tracks and ``absent``
    ones, partners by ``mirror`` too (:func:`joint_walks`); None when no field could be
    placed. The blobs taken are not marked used here."""
    walks = joint_walks(dense, t, lo, hi, spare, params, absent, mirror)
    return None if walks is None else agreed_fill(walks, len(dense), params)


def agreed_fill(walks: tuple, n_tracks: int, params: TrackingParams) -> ChainFill | None:
    """The mean of the two walks of a segment (:func:`joint_walks`' answer) in the runs
    of fields (:func:`~.on_rays.path_runs`) where they agree within :data:`AGREE_MM`
    and the larger expected error is within ``ray_length_max_error_mm``; None if none."""
    grp, rays, fwd, e_f, bwd, e_b = walks
    err = np.fmax(e_f, e_b)
    good = (np.linalg.norm(fwd - bwd, axis=1) <= AGREE_MM) & (err <= params.ray_length_max_error_mm)
    placed = path_runs(good)
    if not placed.any():
        return None
    xyz = np.where(placed[:, None], (fwd + bwd) / 2, np.nan)
    sd = np.where(placed, err, np.nan)
    return ChainFill(xyz, sd, tracks_of(grp.members[1:], n_tracks), rays[0, placed])


def tracks_of(members: NDArray, n_tracks: int) -> tuple[int, ...]:
    """The ``members`` that are tracks (below ``n_tracks``; an absent marker's row is
    none to name as a partner)."""
    return tuple(int(u) for u in members if u < n_tracks)
