"""Single-camera fill through a blob merged with a placed marker's image.

Where one camera alone sees a marker and its image there merges with a neighbour's (an
ankle in line with the heel in the camera's sight), the camera gives one blob at the
intensity centroid of the two images, weighted by their areas, which fall with the
square of the depth (:mod:`kisscal.recon.deblend`). The single-camera fills take no
such blob (:func:`~kisscal.tracking.fill_sphere.alone_blobs`: its ray misses both
markers; lowcost seed 311's ankle, 7-18 mm). When the neighbour is known there
(measured, or placed by a fill with an expected error), its share comes out:
``u = c + w (c - u_o)``, ``w`` the neighbour's area over the marker's
(as :func:`~kisscal.tracking.fill_ends.unmerged`), and the marker lies on the ray of
``u``, at the depth its segment's lengths and its path give
(:func:`~kisscal.tracking.fill_sphere.sphere_depth_fill`).

The neighbour's error ``e_o`` moves ``u`` by ``w`` times its image, a lateral error of
``r³ e_o`` at the marker (``r`` the ratio of their depths), counted with the depth's SD
in the expected error; the field is placed when that is at most
``ray_depth_max_error_mm``. A blob is taken as merged only when its ray passes the
neighbour farther than twice the neighbour's error: nearer, it may be the
neighbour's image alone, the marker hidden behind it.

References
----------
Hartley & Zisserman 2004 (rays of a projective camera); Challis 1995 (segments as rigid
bodies of markers).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import project_rows
from kisscal.tracking.blob_paths import chain_blobs, ray_miss_mm
from kisscal.tracking.fill_sphere import alone_blobs, sphere_depth_fill
from kisscal.tracking.on_rays import ChainFill, path_runs
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs

#: SDs of the neighbour's error its ray must miss it by for a blob to count as merged.
MERGED_SDS = 2.0


def _nearest_other(
    dense: NDArray, t: int, f: NDArray, rows: NDArray, spare: SpareBlobs
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """For each blob ``rows`` (in fields ``f``), the track other than ``t`` that
    projects nearest it there, and that distance (px; inf where no track is known)."""
    xyz = dense[:, f]  # (n_tracks, m, 3)
    cam = np.broadcast_to(spare.camera[rows], xyz.shape[:2])
    proj = project_rows(spare.dlts, cam.ravel(), xyz.reshape(-1, 3)).reshape(*xyz.shape[:2], 2)
    dist = np.linalg.norm(proj - spare.uv_px[rows][None], axis=2)
    dist[t] = np.nan
    dist = np.where(np.isfinite(dist), dist, np.inf)
    o = dist.argmin(axis=0)
    return o, dist[o, np.arange(rows.size)]


def unmerged_blobs(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs,
    params: TrackingParams,
    expected: NDArray,
) -> tuple[NDArray, NDArray, NDArray[np.float64], NDArray[np.float64]]:
    """The marker's blobs in the gap [lo, hi) of track ``t`` that merge with a known
    neighbour's image (within ``ray_merge_px`` of its projection, their rays missing it
    by more than :data:`MERGED_SDS` times its error), as gap offsets, rows, their
    images with the neighbour's share taken out (k, 2) and the lateral error (mm) that
    the neighbour's error puts on the marker (see module). ``expected`` (n_tracks,
    n_fields): the error of each track's known samples (NaN: not known)."""
    ks, rows = chain_blobs(dense[t], lo, hi, spare, params)
    f = lo + ks
    o, dist = _nearest_other(dense, t, f, rows, spare)
    err = np.hypot(expected[o, f], params.ray_length_sd_floor_mm)
    other = dense[o, f]
    merged = (dist <= params.ray_merge_px) & np.isfinite(err)
    merged[merged] = ray_miss_mm(spare, rows[merged], other[merged]) > MERGED_SDS * err[merged]
    ks, rows, other, err, f = ks[merged], rows[merged], other[merged], err[merged], f[merged]
    a, b = dense[t, lo - 1], dense[t, hi]
    near = a + (f - lo + 1)[:, None] / (hi - lo + 1) * (b - a)  # the depth's weight only
    lens = spare.dlts[spare.camera[rows], 8:11]
    # DLT denominators are proportional to depth; the areas fall with its square
    ratio = (np.einsum("ij,ij->i", lens, near) + 1.0) / (np.einsum("ij,ij->i", lens, other) + 1.0)
    c = spare.uv_px[rows]
    uv = c + ratio[:, None] ** 2 * (c - project_rows(spare.dlts, spare.camera[rows], other))
    return ks, rows, uv, ratio**3 * err


def unmerged_depth_fill(
    dense: NDArray,
    t: int,
    lo: int,
    hi: int,
    spare: SpareBlobs | None,
    params: TrackingParams,
    measured: NDArray | None = None,
    known: NDArray | None = None,
    expected: NDArray | None = None,
    mirror: NDArray | None = None,
) -> ChainFill | None:
    """Place fields of the gap [lo, hi) of track ``t`` of ``dense`` on the rays of its
    blobs merged with a known neighbour's image, that share taken out, together with its
    blobs no other image is near (:func:`~kisscal.tracking.fill_sphere.alone_blobs`), at
    the depth :func:`~kisscal.tracking.fill_sphere.sphere_depth_fill` fits (``measured``
    ``known`` and ``mirror`` as there); a field expects that depth's SD and the lateral error of
    its ray (see module). None without ``spare`` or ``expected`` ((n_tracks, n_fields), the error of
    each track's known samples, NaN where not known), or when no merged blob's field is
    placed."""
    series = dense[t]
    if spare is None or expected is None or lo < 1 or hi >= len(series):
        return None
    if not np.all(np.isfinite(series[[lo - 1, hi]])):
        return None
    ks, rows, uv, lateral = unmerged_blobs(dense, t, lo, hi, spare, params, expected)
    if ks.size == 0:
        return None
    a_ks, a_rows = alone_blobs(dense, t, lo, hi, spare, params)
    order = np.argsort(np.r_[ks, a_ks], kind="stable")
    blobs = np.r_[ks, a_ks][order], np.r_[rows, a_rows][order]
    shifted = spare.uv_px.copy()
    shifted[rows] = uv
    moved = dataclasses.replace(spare, uv_px=shifted)
    got = sphere_depth_fill(
        dense, t, lo, hi, moved, params, measured, known, mirror=mirror, blobs=blobs
    )
    if got is None:
        return None
    # the lateral error where the ray is an unmerged blob's (the fit keeps one camera)
    mine = np.isin(got.rows, rows)
    side = np.zeros(hi - lo)
    by_row = np.argsort(rows)
    side[spare.field[got.rows[mine]] - lo] = lateral[
        by_row[np.searchsorted(rows[by_row], got.rows[mine])]
    ]
    sd = np.hypot(got.sd_mm, side)
    placed = path_runs(sd <= params.ray_depth_max_error_mm)
    if not placed[spare.field[got.rows[mine]] - lo].any():
        return None
    xyz, sd = np.where(placed[:, None], got.xyz_mm, np.nan), np.where(placed, sd, np.nan)
    return ChainFill(xyz, sd, got.partners, got.rows[placed[spare.field[got.rows] - lo]])
