"""Single-camera fill with the depth of the joint fill's solutions, smoothed across the gap.

:func:`~kisscal.tracking.fill_joint.joint_ray_fill` places a marker and its segment's
other markers on their blobs' rays together, field by field. Where the segment's
triangle is seen at a poor angle (a toe on one camera's ray, the ankle on another's, the
heel measured: the toe's depth moves by several mm for 1 mm of length) each field's
solution is too loose to keep on its own (expected error above
``ray_length_max_error_mm``), though it is not biased: its errors differ from field to
field. Here they count together, as :mod:`kisscal.tracking.fill_sphere` counts sphere
roots: the marker's distance from the camera over the gap is a random walk on its
acceleration (SD: the RMS second difference of that distance over the trial's measured
samples), with the measured samples on each side as data (SD
``ray_length_sd_floor_mm``) and each field's joint solution as a datum of its expected
error (one per field: the mean of the two walks', the larger error). The walks must
meet: solve a field both, and agree within :data:`~kisscal.tracking.fill_joint.AGREE_MM`
wherever they both do (a walk from one side alone may drift on a wrong solution). A
solution more than three SDs from the fit is dropped and the fit redone. A field is
placed where the posterior SD of its depth is at most ``ray_depth_max_error_mm``, in
runs of at least :data:`~kisscal.tracking.on_rays.MIN_RUN` fields; that SD is its
expected error.

References
----------
Haralick et al. 1994 (three-point perspective pose); Rauch, Tung & Striebel 1965
(fixed-interval smoothing of a random walk); Challis 1995 (segments as rigid bodies of
markers).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import ray_directions
from kisscal.tracking.bodyfill import side_windows
from kisscal.tracking.fill_joint import AGREE_MM, joint_walks, tracks_of
from kisscal.tracking.fill_sphere import MAX_ROUNDS, acceleration_sd, smooth_depth
from kisscal.tracking.on_rays import ChainFill, path_runs
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs


def _solutions(
    fwd: NDArray, e_f: NDArray, bwd: NDArray, e_b: NDArray
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One position and SD per gap field from the two walks: the mean and the larger
    SD where both solved, the one where one did; all NaN unless the walks meet (both
    solved a field) and agree wherever they do: a walk from one side alone may follow
    a wrong solution that drifts on smoothly (a tibia 2, 4, 7, 9 mm off in four fields)."""
    both = np.isfinite(e_f) & np.isfinite(e_b)
    agree = np.linalg.norm(fwd - bwd, axis=1) <= AGREE_MM
    if not both.any() or not agree[both].all():
        return np.full_like(fwd, np.nan), np.full_like(e_f, np.nan)
    xyz = np.where(np.isfinite(e_f)[:, None], fwd, bwd)
    xyz = np.where(both[:, None], (fwd + bwd) / 2, xyz)
    sd = np.where(both, np.fmax(e_f, e_b), np.fmin(e_f, e_b))
    return np.where(np.isfinite(sd)[:, None], xyz, np.nan), sd


def _fit(
    n: int,
    ends: tuple[NDArray, NDArray, NDArray],
    data: tuple[NDArray, NDArray, NDArray],
    acc: float,
) -> tuple[NDArray, NDArray, NDArray[np.bool_]]:
    """:func:`~kisscal.tracking.fill_sphere.smooth_depth` on ``ends`` and ``data``
    (index, depth, SD each), data more than three SDs from the fit dropped one at a
    time (the worst first). Returns the mean, its SD and which data were kept."""
    idx, val, sd = data
    use = np.ones(idx.size, dtype=bool)
    for _ in range(MAX_ROUNDS):
        mean, msd = smooth_depth(
            n, np.r_[ends[0], idx[use]], np.r_[ends[1], val[use]], np.r_[ends[2], sd[use]], acc
        )
        miss = np.where(use, np.abs(val - mean[idx]) / sd, 0.0)
        if not np.any(miss > 3.0):
            break
        use[np.argmax(miss)] = False
    return mean, msd, use


def joint_depth_fill(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    params: TrackingParams,
    measured: NDArray | None = None,
    absent: NDArray | None = None,
    mirror: NDArray | None = None,
) -> ChainFill | None:
    """Place fields of the gap [lo, hi) of track ``t`` on the rays of its own blobs in
    the camera that sees most of the gap, at the depth fitted to its samples on each
    side and the joint fill's solutions (see module); None when no run of
    :data:`~kisscal.tracking.on_rays.MIN_RUN` fields is placed or no solution was
    used. With ``measured`` ((n_fields,) bool), the ends of the fit are only those
    samples of the track; ``absent``, ``mirror``: rows of markers no track took
    (:func:`~kisscal.tracking.fill_joint.joint_walks`). The blobs taken are not marked
    used here."""
    walks = joint_walks(dense, t, lo, hi, spare, params, absent, mirror)
    if walks is None:
        return None
    grp, rays, fwd, e_f, bwd, e_b = walks
    ks = np.flatnonzero(rays[0] >= 0)
    cam = int(np.bincount(spare.camera[rays[0, ks]]).argmax())
    ks = ks[spare.camera[rays[0, ks]] == cam]
    centre = spare.centres[cam]
    own = dense[t] if measured is None else np.where(measured[:, None], dense[t], np.nan)
    acc = acceleration_sd(own, centre)
    before, after = side_windows(own, lo, hi, params.fill_context_fields)
    xyz, sd = _solutions(fwd, e_f, bwd, e_b)
    k_data = ks[np.isfinite(sd[ks])]
    if before.size < 2 or after.size < 2 or not acc > 0 or k_data.size == 0:
        return None
    f0 = int(before[0])
    # samples other fills placed beside the gap: data of their largest expected error
    span = np.arange(f0, int(after[-1]) + 1)
    placed = span[np.isfinite(dense[t, span, 0]) & ~np.isfinite(own[span, 0])]
    ends_f = np.r_[before, after, placed]
    ends = (
        ends_f - f0,
        np.linalg.norm(dense[t, ends_f] - centre, axis=1),
        np.r_[
            np.full(before.size + after.size, params.ray_length_sd_floor_mm),
            np.full(placed.size, params.ray_length_max_error_mm),
        ],
    )
    data = (k_data + lo - f0, np.linalg.norm(xyz[k_data] - centre, axis=1), sd[k_data])
    mean, msd, use = _fit(int(after[-1]) + 1 - f0, ends, data, acc)
    if not use.any():
        return None
    rows = rays[0, ks]
    d = ray_directions(spare.dlts[spare.camera[rows]], spare.uv_px[rows])
    d *= np.sign((dense[t, lo - 1] - centre) @ d.T)[:, None]  # towards the marker
    at = centre + mean[ks + lo - f0, None] * d
    good = np.zeros(hi - lo, dtype=bool)
    good[ks] = msd[ks + lo - f0] <= params.ray_depth_max_error_mm
    placed = path_runs(good)
    take = placed[ks]
    if not take.any():
        return None
    out, err = np.full((hi - lo, 3), np.nan), np.full(hi - lo, np.nan)
    out[ks[take]] = at[take]
    err[ks[take]] = msd[ks[take] + lo - f0]
    return ChainFill(out, err, tracks_of(grp.members[1:], len(dense)), rows[take])
