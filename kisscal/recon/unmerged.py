"""Two-camera points holding a merged blob: not evidence of a marker.

A marker whose image merges with a neighbour's in two cameras (a different neighbour in
each, as an ankle between heel and toe) gives two blobs at the intensity centroids of the
unions (:mod:`kisscal.recon.deblend`), which may well meet on their epipolar lines: their
pair triangulates with a small residual, yet off the marker by the centroids' shift times
the depth over the focal length (seed 304 of the lowcost rig: 20 mm, 0.02 px). Neither blob
is the point's own, so the pair proves nothing; it also holds the blobs that
:func:`~kisscal.recon.deblend.deblend_merged` would deblend with the marker's clean blob in
a third camera. One merged blob is enough: its centroid's shift moves the pair along the
other camera's ray all the same (lowcost seed 304 fields 71-72, the ankle 13.7 and
12.6 mm off, its blob in the other camera its own, the heel's image 3.0 px from it and
not merged). Such a pair is dropped before deblending, and kept where no new point
takes one of its blobs. Its clean blob serves a new point only if the deblended pair
fits it better than the pulled one by more than noise: a blob beside the image of a
marker hidden from its camera is flagged the same way (lowcost seed 307's toe beside its
heel's image), and deblended as if merged it would be 26-31 mm off. Nor does a new point
whose own blob lies beside the predicted image of another trajectory, a marker with no
point there yet (:func:`predicted_beside`): that blob may hold it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import project_rows
from kisscal.recon.deblend import MergeScene, depth_of, near_blobs, solve_deblended
from kisscal.recon.hidden import predictions


def merged_pairs(
    scene: MergeScene,
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
    blob_row: NDArray[np.int64],
) -> NDArray[np.bool_]:
    """Two-camera points one of whose blobs at least is merged (:func:`shared_blobs`).

    Parameters
    ----------
    scene : MergeScene
        The trial's 2D table and rig.
    p_field, p_xyz : ndarray, shapes (m,), (m, 3)
        The trial's points.
    blob_row : ndarray of int, shape (m, n_cameras)
        Row of each point's blob per camera (-1: none).

    Returns
    -------
    ndarray of bool, shape (m,)
    """
    shared = shared_blobs(scene, p_field, p_xyz, blob_row)
    n_shared = np.sum(shared[blob_row] & (blob_row >= 0), axis=1)
    return ((blob_row >= 0).sum(axis=1) == 2) & (n_shared >= 1)


def shared_blobs(
    scene: MergeScene,
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
    blob_row: NDArray[np.int64],
) -> NDArray[np.bool_]:
    """Blobs of the 2D table held by a point and within ``params.deblend_radius_px`` of
    another point's projection in its field (merged with that point's image); arguments
    as :func:`merged_pairs`. Returns a mask of shape (n_blobs,)."""
    owner = np.full(len(scene.field), -1, dtype=np.int64)
    k, _ = np.nonzero(blob_row >= 0)
    owner[blob_row[blob_row >= 0]] = k
    held = owner >= 0
    point, blob, _ = near_blobs(scene, p_field, p_xyz, held)
    shared = np.zeros(len(scene.field), dtype=bool)
    shared[blob[owner[blob] != point]] = True  # near a point that is not its owner's
    return shared


def deblended_in(blob_row: NDArray[np.int64], rows: NDArray[np.int64]) -> NDArray[np.bool_]:
    """Points one of whose blobs a new point took (one of ``rows``, its merged and own
    blobs): replaced by it, where a new point of the same field may be another marker's.

    Parameters
    ----------
    blob_row : ndarray of int, shape (m, n_cameras)
        Row of each point's blob per camera (-1: none).
    rows : ndarray of int, shape (k,)
        Blobs of the new points (:class:`~kisscal.recon.deblend.Deblended`).

    Returns
    -------
    ndarray of bool, shape (m,)
    """
    return np.any(np.isin(blob_row, rows) & (blob_row >= 0), axis=1)


def predicted_beside(
    scene: MergeScene,
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    xyz_mm: NDArray[np.float64],
    row: NDArray[np.int64],
) -> NDArray[np.bool_]:
    """New points (``field``, ``xyz_mm``) whose blob ``row`` lies within
    ``params.deblend_radius_px`` of the image of the constant-velocity prediction of
    another trajectory that stops there (:func:`~kisscal.recon.hidden.predictions`
    through the points ``p_field``, ``p_xyz``; another's: farther than
    ``two_camera_continuity_mm`` from the new point): the blob may be that marker's,
    merged with it or its alone (lowcost seed 303 field 391: the ankle's blob, merged
    with the heel's, deblended as the heel's own, 20.7 mm off). A trajectory that goes on
    through a point of its own there does not count (seed 306 field 340: the ankle's
    own blob 2.8 px from the image of the heel, hidden from that camera)."""
    params = scene.params
    tol = params.two_camera_continuity_mm
    pf, pxyz, stops = predictions(p_field, p_xyz, params.two_camera_step_mm, tol)
    # a trajectory with a point there accounts for its marker: a blob beside its image
    # is a marker's hidden from that camera, as shared_blobs judges held ones
    pf, pxyz = pf[stops], pxyz[stops]
    out = np.zeros(len(row), dtype=bool)
    if len(pf) == 0 or len(row) == 0:
        return out
    order = np.argsort(pf, kind="stable")
    pf, pxyz = pf[order], pxyz[order]
    lo = np.searchsorted(pf, field, side="left")
    n = np.searchsorted(pf, field, side="right") - lo
    k = np.repeat(np.arange(len(row)), n)
    q = np.repeat(lo - np.cumsum(n) + n, n) + np.arange(n.sum())
    other = np.linalg.norm(pxyz[q] - xyz_mm[k], axis=1) > tol
    k, q = k[other], q[other]
    img = project_rows(scene.dlts, scene.camera[row[k]], pxyz[q])
    near = np.linalg.norm(img - scene.uv[row[k]], axis=1) <= params.deblend_radius_px
    out[k[near]] = True
    return out


def predicted_pairs(
    scene: MergeScene,
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
    blob_row: NDArray[np.int64],
) -> NDArray[np.bool_]:
    """Two-camera points each of whose blobs lies beside the predicted image of another
    trajectory that stops there (:func:`predicted_beside`): both blobs may hold a marker
    the pair leaves without a point, and the pair sits off its own (lowcost seed 307
    field 397: the ankle's pair of blobs merged with the toe's and with the heel's, 14.7 mm
    off, both of these lost there). Arguments as :func:`merged_pairs`."""
    two = np.flatnonzero((blob_row >= 0).sum(axis=1) == 2)
    rows = np.sort(blob_row[two], axis=1)[:, -2:]
    f, xyz = np.repeat(p_field[two], 2), np.repeat(p_xyz[two], 2, axis=0)
    beside = predicted_beside(scene, p_field, p_xyz, f, xyz, rows.ravel()).reshape(-1, 2)
    out = np.zeros(len(p_field), dtype=bool)
    out[two[beside.all(axis=1)]] = True
    return out


def pulled_pairs(
    scene: MergeScene,
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
    blob_row: NDArray[np.int64],
    rms_px: NDArray[np.float64],
) -> NDArray[np.bool_]:
    """Two-camera points that a merge explains better than the marker alone.

    A blob of a pair within ``params.deblend_radius_px`` of another point's projection
    may hold both markers. Deblended (the other's share taken out, as
    :func:`~kisscal.recon.deblend.deblend_merged` does) with the pair's other blob, it
    triangulates with a residual; where that is smaller than the pair's by more than the
    trial's median residual (a marker's noise), the blobs fit the merge, and the pair sits
    off its marker along the clean camera's ray (the merged centroid's shift times the
    depth over the focal length; lowcost seed 362 field 324: the ankle merged with the
    heel, 14.3 mm off, 0.099 px against 0.030 deblended). Nor is the deblended point sure
    (a blob beside the image of a marker hidden from its camera fits it too, lowcost seed
    313): such a pair is no measurement. Arguments as :func:`merged_pairs`, and each
    point's ``rms_px`` (m,). Returns a mask of shape (m,).
    """
    out = np.zeros(len(p_field), dtype=bool)
    two = np.flatnonzero((blob_row >= 0).sum(axis=1) == 2)
    if len(two) == 0:
        return out
    rows = np.sort(blob_row[two], axis=1)[:, -2:]  # each pair's two blobs
    held = np.zeros(len(scene.field), dtype=bool)
    held[rows.ravel()] = True
    params = scene.params
    q, b, proj = near_blobs(scene, p_field, p_xyz, held)
    # every (pair, blob of it, other point near that blob); a blob may be two pairs'
    flat = rows.ravel()
    order = np.argsort(flat, kind="stable")
    lo = np.searchsorted(flat[order], b, side="left")
    n = np.searchsorted(flat[order], b, side="right") - lo
    hit = np.repeat(np.arange(len(b)), n)
    slot = order[np.repeat(lo - np.cumsum(n) + n, n) + np.arange(n.sum())]
    k, side = slot // 2, slot % 2
    other = two[k] != q[hit]
    hit, k, side = hit[other], k[other], side[other]
    if len(hit) == 0:
        return out
    merged, clean = rows[k, side], rows[k, 1 - side]
    cams = np.column_stack([scene.camera[clean], scene.camera[merged]])
    depth = depth_of(scene.dlts, cams[:, 1], p_xyz[q[hit]])
    xyz, rms, image = solve_deblended(
        scene.dlts,
        cams,
        scene.uv[clean],
        scene.uv[merged],
        proj[hit],
        1.0 / depth**2,
        2,
        params.reweight_iterations,
    )
    typical = float(np.median(rms_px[np.isfinite(rms_px)]))
    better = np.all(np.isfinite(xyz), axis=1) & (rms + typical < rms_px[two[k]])
    # an image moved further than a marker's radius is no merge (as deblend_merged)
    better &= np.linalg.norm(image - scene.uv[merged], axis=1) <= 2.0 * params.deblend_radius_px
    # and the merge moves it by more than a pair's error may be
    better &= np.linalg.norm(xyz - p_xyz[two[k]], axis=1) > params.merged_pull_mm
    out[two[k[better]]] = True
    return out
