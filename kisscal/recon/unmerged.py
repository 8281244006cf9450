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
heel's image), and deblended as if merged it would be 26-31 mm off.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import project_rows
from kisscal.recon.deblend import MergeScene, near_blobs


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
    point, blob, _ = near_blobs(
        p_field,
        p_xyz,
        scene.field,
        scene.camera,
        scene.uv,
        held,
        scene.dlts,
        scene.params.deblend_radius_px,
    )
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


def on_left_blobs(
    scene: MergeScene,
    blob_row: NDArray[np.int64],
    shared: NDArray[np.bool_],
    xyz_mm: NDArray[np.float64],
    rms_px: NDArray[np.float64],
    own_row: NDArray[np.int64],
    merged_row: NDArray[np.int64],
) -> NDArray[np.bool_]:
    """New points that fit every blob they leave of a pair they take a blob from: a
    clean blob as a third view of the point, the reprojection RMS over its own two blobs
    (``rms_px``) and that one within the trial's residual limit ``scene.limit_px``; a
    merged one (``shared``) within ``params.deblend_radius_px`` of its projection. A
    pair pulled by a merged blob moves along its clean blob's ray, and its marker lies on
    that ray too; a new point off it is another marker's (lowcost seed 303 field 391: the
    heel's pair of its own blobs, one beside the hidden toe's image, taken with the
    ankle-and-heel blob of a third camera, 20.7 mm off and 1.8 px from the pair's clean
    blob; seed 304's ankle deblended 2.3 mm off projects 0.26 px from it, RMS 0.16 px).

    Parameters
    ----------
    scene : MergeScene
        The trial's 2D table and rig.
    blob_row : ndarray of int, shape (m, n_cameras)
        Blobs of the pairs given way (-1: none).
    shared : ndarray of bool, shape (n_blobs,)
        Merged blobs (:func:`shared_blobs`).
    xyz_mm : ndarray, shape (k, 3)
        The new points, each with its ``rms_px``, ``own_row`` and ``merged_row`` (k,).

    Returns
    -------
    ndarray of bool, shape (k,)
    """
    pair = np.full(len(scene.field), -1, dtype=np.int64)
    k, _ = np.nonzero(blob_row >= 0)
    pair[blob_row[blob_row >= 0]] = k
    ok = np.ones(len(xyz_mm), dtype=bool)
    for taken in (own_row, merged_row):
        j = np.flatnonzero(pair[taken] >= 0)
        rows = blob_row[pair[taken[j]]]  # (len(j), n_cameras)
        left = (rows >= 0) & (rows != own_row[j, None]) & (rows != merged_row[j, None])
        jj, c = np.nonzero(left)
        b = rows[jj, c]
        at = project_rows(scene.dlts, scene.camera[b], xyz_mm[j[jj]])
        d = np.linalg.norm(at - scene.uv[b], axis=1)
        # the point held where it is: an upper bound of its three-view RMS
        three = np.sqrt((2.0 * rms_px[j[jj]] ** 2 + d**2) / 3.0)
        far = np.where(
            shared[b], ~(d <= scene.params.deblend_radius_px), ~(three <= scene.limit_px)
        )
        ok[j[jj[far]]] = False
    return ok
