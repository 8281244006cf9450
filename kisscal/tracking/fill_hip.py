"""Single-camera fill of a marker about a joint centre whose own markers are on rays:
a thigh marker placed with the pelvis and the hip centre.

The joint fill (:mod:`kisscal.tracking.fill_joint`) solves the depths of a segment's
markers on rays from the segment's lengths. A thigh marker seen by one camera while its
knee marker is seen by none has one length partner too few; the hip centre
(:mod:`kisscal.tracking.joint_centres`) is a second one, but only where the pelvis is
known. With the whole pelvis on one camera (modern 3 seed 353, RTHI 176-221) its three
rays and three lengths alone fix it with no length to spare (a wrong blob would go
unseen). Solved together with the thigh they do spare one: the pelvis's depths, the
thigh marker's depth on its ray, and the knee marker as a free point held by its
lengths to the hip centre, the thigh marker and the measured shank (its hinge axis),
fit more lengths than unknowns; where an untracked blob lies alone where they put the
knee, on its ray (353's knee: its track starts 130 fields later), they spare two. The
hip centre is carried in the frame of three pelvis markers as fixed coefficients of its
two edges and their cross product (constant for a rigid triangle): it moves with the
depths.

Per field, the unknowns are found by Gauss-Newton on every length of the segment's
markers, of the knee's partners and to the centre whose SD in the trial is at most
``rigid_fill_sd_mm`` (weighed by ``1 / SD²``, SD at least ``ray_length_sd_floor_mm``,
a filled anchor's expected error added), from the previous field's solution, walking
the gap from each side as the joint fill does; a field is kept where the lengths spare
one, both walks agree within :data:`~kisscal.tracking.fill_joint.AGREE_MM`, every length
fits within three SDs, and the target's expected error along its ray (the solution's
covariance) is at most ``ray_length_max_error_mm``. In the trusted pass, once every other
fill is made (:func:`trusted_hip`), the fill is made again with the fields placed since as
edges (a thigh carried about the hip and its knee where no camera saw it), expecting up
to ``params.trusted_max_error_mm``: where the knee is on a ray too, the covariance of the two
depths says 5-5.5 mm along the thigh's ray; where the ray grazes the spheres it says more
and the field is refused (modern 3 seed 436 RTHI: 6-11 mm expected, left open).

References
----------
Gamage & Lasenby 2002 (the joint centre); Haralick et al. 1994 (a rigid triangle on
three rays); Hartley & Zisserman 2004 (rays of a projective camera).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import project_rows, ray_directions
from kisscal.tracking.bodyfill import distance_sd
from kisscal.tracking.fill_joint import (
    ITERS,
    STEP_MM,
    agreed_fill,
    edge_positions,
    fit_summary,
    member_rays,
    pick_rays,
)
from kisscal.tracking.fill_place import take_placed
from kisscal.tracking.gap_record import Gap
from kisscal.tracking.joint_centres import joint_centres
from kisscal.tracking.on_rays import ChainFill
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs
from kisscal.tracking.segment_lengths import length_partners

#: Step (mm) of the numerical derivative of the lengths.
EPS_MM = 1e-3


def centre_coefficients(frame: NDArray, centre: NDArray) -> NDArray[np.float64]:
    """The fixed coefficients (3,) of ``centre`` (n, 3) in the frame of three markers
    ``frame`` (3, n, 3): its offset from the first as a combination of the two edges from
    it and their cross product, the median over the fields where all are known (NaN
    where none is)."""
    ok = np.all(np.isfinite(frame[..., 0]), axis=0) & np.isfinite(centre[:, 0])
    if not ok.any():
        return np.full(3, np.nan)
    p = frame[:, ok]
    basis = np.stack([p[1] - p[0], p[2] - p[0], np.cross(p[1] - p[0], p[2] - p[0])], axis=2)
    return np.median(np.linalg.solve(basis, (centre[ok] - p[0])[..., None])[..., 0], axis=0)


def carried_centre(p: NDArray, coef: NDArray) -> NDArray[np.float64]:
    """The centre of :func:`centre_coefficients` for frame markers ``p`` (..., 3, 3)."""
    e1, e2 = p[..., 1, :] - p[..., 0, :], p[..., 2, :] - p[..., 0, :]
    return p[..., 0, :] + coef[0] * e1 + coef[1] * e2 + coef[2] * np.cross(e1, e2)


def _spheres(p: NDArray, r: NDArray) -> list[NDArray]:
    """The points (one or two) nearest where three spheres (centres ``p`` (3, 3), radii
    ``r`` (3,)) meet: a start for a free point held by three lengths."""
    ex = p[1] - p[0]
    d = np.linalg.norm(ex)
    ex = ex / d
    i = ex @ (p[2] - p[0])
    ey = p[2] - p[0] - i * ex
    j = np.linalg.norm(ey)
    ey = ey / max(j, 1e-9)
    x = (r[0] ** 2 - r[1] ** 2 + d**2) / (2 * d)
    y = (r[0] ** 2 - r[2] ** 2 + i**2 + j**2 - 2 * i * x) / (2 * max(j, 1e-9))
    z = np.sqrt(max(r[0] ** 2 - x**2 - y**2, 0.0))
    base = p[0] + x * ex + y * ey
    ez = np.cross(ex, ey)
    return [base + z * ez, base - z * ez]


class _Hip:
    """Track ``t``'s group: its length partners, theirs, and a centre cluster's frame;
    lengths (mean, SD; inf where not rigid) among them and to the centre (last row)."""

    def __init__(self, dense: NDArray, t: int, params: TrackingParams, mirror: NDArray | None):
        self.ok = False
        centres = joint_centres(dense, t, params, mirror)
        if not centres.clusters:
            return
        frame = np.asarray(centres.clusters[0][:3], dtype=np.int64)
        own = length_partners(dense, t, params, mirror)[0]
        second = [length_partners(dense, int(u), params, mirror)[0] for u in own]
        members = list(dict.fromkeys([t, *own.tolist(), *np.concatenate([[], *second])]))
        members = [int(u) for u in members if u not in frame] + frame.tolist()
        self.members = np.asarray(members, dtype=np.int64)
        self.frame = np.arange(len(members) - 3, len(members))
        self.free_ok = np.isin(self.members, own)  # may be held by lengths alone
        self.coef = centre_coefficients(dense[frame], centres.xyz_mm[0])
        series = np.concatenate([dense[self.members], centres.xyz_mm[:1]])
        sd = distance_sd(series, series)
        sd = np.where(
            sd <= params.rigid_fill_sd_mm, np.maximum(sd, params.ray_length_sd_floor_mm), np.inf
        )
        np.fill_diagonal(sd, np.inf)
        # the frame is another segment: the centre, not a length, links it to the rest
        # (a knee measured 70 fields kept its distance to two pelvis markers by chance)
        rest = np.r_[np.arange(len(members) - 3), len(members)]
        sd[np.ix_(self.frame, rest)] = sd[np.ix_(rest, self.frame)] = np.inf
        dist = np.linalg.norm(series[:, None] - series[None], axis=3)
        seen = np.isfinite(dist)
        self.length = np.where(seen, dist, 0.0).sum(axis=2) / np.maximum(seen.sum(axis=2), 1)
        self.sd = sd
        self.ok = bool(np.all(np.isfinite(self.coef))) and np.isfinite(sd[0, -1])


def _points(z: NDArray, kind: NDArray, base: NDArray, d: NDArray, grp: _Hip) -> NDArray:
    """Every member's point and the centre (k, m + 1, 3) for k sets of unknowns ``z``
    (k, u): per member ``kind`` 1 (a depth on its ray ``base + s d``), 2 (a free
    point), else ``base``."""
    pts = np.repeat(base[None], len(z), axis=0)
    ray, free = np.flatnonzero(kind == 1), np.flatnonzero(kind == 2)
    pts[:, ray] = base[ray] + z[:, : ray.size, None] * d[ray]
    pts[:, free] = z[:, ray.size :].reshape(len(z), -1, 3)
    return np.concatenate([pts, carried_centre(pts[:, grp.frame], grp.coef)[:, None]], axis=1)


def _solve(z0: NDArray, kind: NDArray, base: NDArray, d: NDArray, grp: _Hip, sd: NDArray):
    """Gauss-Newton on the lengths ``(i, j)`` of finite ``sd`` (m + 1, m + 1); returns
    the unknowns, the largest residual in SDs and the target's depth SD (inf when the
    lengths do not spare one or do not fix it)."""
    i, j = np.nonzero(np.triu(np.isfinite(sd)))
    z = z0.astype(float).copy()
    if i.size < z.size + 1:
        return z, np.inf, np.inf
    w = 1.0 / sd[i, j]

    def res(v: NDArray) -> NDArray:  # (k, u) unknowns: (k, pairs) residuals
        p = _points(v, kind, base, d, grp)
        return (np.linalg.norm(p[:, i] - p[:, j], axis=2) - grp.length[i, j]) * w

    step = np.full(z.size, np.inf)
    for it in range(ITERS + 1):
        both = res(z + np.r_[np.zeros((1, z.size)), EPS_MM * np.eye(z.size)])
        r, jac = both[0], ((both[1:] - both[0]) / EPS_MM).T
        info = jac.T @ jac
        if it == ITERS or np.abs(step).max() < 0.01:  # converged: a hundredth of a mm
            break
        step = np.clip(np.linalg.lstsq(info, jac.T @ r, rcond=None)[0], -100.0, 100.0)
        z -= step
    return fit_summary(z, r, info)


def _walk(
    dense: NDArray,
    grp: _Hip,
    rays: NDArray,
    errors: NDArray,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    forward: bool,
    gate_px: float,
) -> tuple[NDArray, NDArray]:
    """Target position and expected error per field of [lo, hi) (NaN where not solved),
    solved field by field from one side of the gap; ``rays`` the members' spare rows
    (m, hi - lo), ``errors`` their samples' expected errors (m, n_fields), a free
    point's own blob looked for within ``gate_px`` of where the lengths put it."""
    n, m = hi - lo, len(grp.members)
    xyz, err = np.full((n, 3), np.nan), np.full(n, np.nan)
    last = edge_positions(dense[grp.members], lo, hi, forward)
    edge, step = (lo - 1, -1) if forward else (hi, 1)
    vel = np.nan_to_num(dense[grp.members[0], edge] - dense[grp.members[0], edge + step])
    since = 0
    for k in range(n) if forward else range(n - 1, -1, -1):
        f, since = lo + k, since + 1
        here = dense[grp.members, f]
        known = np.isfinite(here[:, 0])
        kind = np.where(known, 0, np.where(rays[:, k] >= 0, 1, np.where(grp.free_ok, 2, 3)))
        kind[(kind == 1) & ~np.isfinite(last[:, 0])] = 3
        if kind[0] != 1 or np.any(kind[grp.frame] == 3):
            continue
        ray = np.flatnonzero(kind == 1)
        base, d = np.where(known[:, None], here, 0.0), np.zeros((m, 3))
        cam = spare.camera[rays[ray, k]]
        base[ray] = spare.centres[cam]
        d[ray] = ray_directions(spare.dlts[cam], spare.uv_px[rays[ray, k]])
        # a filled anchor's error counts in its lengths, the frame's in the centre's
        extra = np.r_[np.where(known, np.nan_to_num(errors[:, f]), 0.0), 0.0]
        lever = np.abs(np.r_[1 - grp.coef[:2].sum(), grp.coef[:2]]).sum()
        extra[-1] = np.max(extra[grp.frame]) * lever
        use = np.r_[kind != 3, True]
        sd = np.where(np.outer(use, use), np.hypot(grp.sd, np.hypot.outer(extra, extra)), np.inf)
        fixed = np.r_[known, known[grp.frame].all()]  # lengths among fixed points tell nothing
        sd[np.ix_(fixed, fixed)] = np.inf
        starts = _starts(last, kind, base, d, grp, np.where(known[:, None], here, last))
        z, worst, e = min((_solve(z0, kind, base, d, grp, sd) for z0 in starts), key=_fit)
        x = _points(z[None], kind, base, d, grp)[0]
        for u in np.flatnonzero(kind == 2).tolist():  # a free point's own blob, if one
            row = _blob_near(spare, f, x[u], rays[:, k], gate_px)
            if row >= 0:
                kind[u], cam = 1, spare.camera[row]
                base[u] = spare.centres[cam]
                d[u] = ray_directions(spare.dlts[[cam]], spare.uv_px[[row]])[0]
                on, free = kind == 1, np.r_[kind == 2, False]
                z0 = np.r_[np.einsum("ij,ij->i", x[:-1][on] - base[on], d[on]), x[free].ravel()]
                z, worst, e = _solve(z0, kind, base, d, grp, sd)
                x = _points(z[None], kind, base, d, grp)[0]
        if worst <= 3.0 and np.linalg.norm(x[0] - last[0] - since * vel) <= STEP_MM:
            xyz[k], err[k] = x[0], e
            vel, since = (x[0] - last[0]) / since, 0
            last[kind != 3] = x[:-1][kind != 3]
        last[known] = here[known]
    return xyz, err


def _fit(got: tuple) -> float:
    """A solution's largest residual (the start to keep)."""
    return got[1]


def _blob_near(spare: SpareBlobs, f: int, x: NDArray, taken: NDArray, gate_px: float) -> int:
    """The free blob of field ``f`` nearest the projection of ``x`` in its camera, within
    ``gate_px`` and clearly nearer than any other (half the distance), not one of the
    rows ``taken``; -1 for none."""
    a, b = np.searchsorted(spare.field, [f, f + 1])
    rows = np.arange(a, b)
    rows = rows[spare.free[rows] & ~np.isin(rows, taken)]
    if rows.size == 0:
        return -1
    at = project_rows(spare.dlts, spare.camera[rows], np.tile(x, (rows.size, 1)))
    miss = np.linalg.norm(spare.uv_px[rows] - at, axis=1)
    order = np.argsort(miss)
    near = miss[order]
    if near[0] > gate_px or (near.size > 1 and near[1] < 2.0 * near[0]):
        return -1
    return int(rows[order[0]])


def _starts(
    last: NDArray, kind: NDArray, base: NDArray, d: NDArray, grp: _Hip, near: NDArray
) -> list[NDArray]:
    """Starts of :func:`_solve`: each depth at the member's last position, a free point
    at its last position or, never known, where its three least varying lengths to the
    points known meet (both ways)."""
    ray = np.flatnonzero(kind == 1)
    depths = np.einsum("ij,ij->i", last[ray] - base[ray], d[ray])
    out = [depths]
    for u in np.flatnonzero(kind == 2).tolist():
        if np.isfinite(last[u, 0]):
            out = [np.r_[z, last[u]] for z in out]
            continue
        have = np.flatnonzero(np.isfinite(near[:, 0]) & np.isfinite(grp.sd[u, :-1]))
        have = have[np.argsort(grp.sd[u, have])][:3]
        if have.size < 3:
            return [np.r_[depths, np.zeros(3 * int(np.sum(kind == 2)))]]
        pts = _spheres(near[have], grp.length[u, have])
        out = [np.r_[z, p] for z in out for p in pts]
    return out


def hip_ray_fill(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    params: TrackingParams,
    absent: NDArray | None = None,
    mirror: NDArray | None = None,
    errors: NDArray | None = None,
) -> ChainFill | None:
    """Place fields of the gap [lo, hi) of track ``t`` on its own blob's rays together
    with the markers carrying its joint centre on theirs (see module); ``absent`` rows
    of markers no track took, ``mirror`` for the partners, ``errors`` each sample's
    expected error (counted where a partner was filled). None when no field could be
    placed. The blobs taken are not marked used here."""
    if absent is not None:
        dense = np.concatenate([dense, absent])
    if lo < 2 or hi + 1 >= dense.shape[1] or not np.all(np.isfinite(dense[t, [lo - 1, hi]])):
        return None
    grp = _Hip(dense, t, params, mirror)
    if not grp.ok:
        return None
    rays = pick_rays(
        np.stack([member_rays(dense, int(u), lo, hi, spare, params, mirror) for u in grp.members])
    )
    held = (rays[grp.frame] >= 0) | np.isfinite(dense[grp.members[grp.frame], lo:hi, 0])
    if not np.any(rays[0] >= 0) or not np.any(np.all(held, axis=0)):
        return None
    own = np.where(np.isfinite(dense[grp.members, :, 0]), 0.0, np.nan)
    if errors is not None:
        own = np.where(np.isnan(own), errors[grp.members], own)
    own = np.where(np.isnan(own), params.ray_rest_max_error_mm, own)
    gate = 8.0 * params.ray_chain_gate_px
    fwd, e_f = _walk(dense, grp, rays, own, lo, hi, spare, True, gate)
    bwd, e_b = _walk(dense, grp, rays, own, lo, hi, spare, False, gate)
    return agreed_fill((grp, rays, fwd, e_f, bwd, e_b), len(dense), params)


def trusted_hip(gap: Gap, a: int, b: int, params: TrackingParams) -> NDArray[np.bool_]:
    """The hip fill (:func:`hip_ray_fill`) of fields [a, b) of ``gap`` (a
    :class:`~kisscal.tracking.gap_record.Gap`) once every other fill is made, the walks from
    both sides agreeing, expecting at most ``params.trusted_max_error_mm`` (its error along
    the ray from the lengths' geometry: where the ray meets the spheres at a glancing
    angle the covariance says so, and over that it is refused); placed fields are
    written into ``gap.dense`` and their blobs taken. Returns the fields placed."""
    cap = max(params.ray_length_max_error_mm, params.trusted_max_error_mm)
    got = hip_ray_fill(
        gap.dense,
        gap.t,
        a,
        b,
        gap.spare,
        params.replace(ray_length_max_error_mm=cap),
        gap.absent,
        gap.mirror,
        gap.errors,
    )
    if got is None:
        return np.zeros(b - a, dtype=bool)
    gap.out.extend(take_placed(gap.dense, gap.t, a, got, gap.spare))
    return np.isfinite(got.sd_mm)
