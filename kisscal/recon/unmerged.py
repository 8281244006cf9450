"""Two-camera points made of two merged blobs: not evidence of a marker.

A marker whose image merges with a neighbour's in two cameras (a different neighbour in
each, as an ankle between heel and toe) gives two blobs at the intensity centroids of the
unions (:mod:`kisscal.recon.deblend`), which may well meet on their epipolar lines: their
pair triangulates with a small residual, yet off the marker by the centroids' shift times
the depth over the focal length (seed 304 of the lowcost rig: 20 mm, 0.02 px). Neither blob
is the point's own, so the pair proves nothing; it also holds the blobs that
:func:`~kisscal.recon.deblend.deblend_merged` would deblend with the marker's clean blob in
a third camera. Such a pair is dropped before deblending.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.recon.deblend import MergeScene, near_blobs


def merged_pairs(
    scene: MergeScene,
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
    blob_row: NDArray[np.int64],
) -> NDArray[np.bool_]:
    """Two-camera points each of whose blobs lies within ``params.deblend_radius_px`` of
    another point's projection in its field (a merged blob).

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
    n_blobs = (blob_row >= 0).sum(axis=1)
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
    n_shared = np.bincount(owner[shared], minlength=len(p_field))
    return (n_blobs == 2) & (n_shared == 2)
