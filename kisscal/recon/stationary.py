"""Removal of stationary false detections (Küçük 2005, 3.3.1).

LEDs of the other cameras and fixed reflections appear at the same image place in nearly
every field, while marker images move. Over a whole trial, a detection is stationary when
detections of the same camera sit within a small neighbourhood of it in more than a set
fraction of the fields; all such detections are removed. The neighbourhood radius absorbs
the few-pixel wander of a stationary spot; keeping it small spares moving markers that
cross the spot.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.errors import KisscalError


def stationary_mask(
    field: ArrayLike,
    camera: ArrayLike,
    uv: ArrayLike,
    radius_px: float = 1.5,
    fraction: float = 0.5,
) -> NDArray[np.bool_]:
    """Flag detections that stay at one image place through a trial.

    Parameters
    ----------
    field, camera : array_like of int, shape (n,)
        Field index and camera of each 2D detection (long format, one row per blob).
    uv : array_like, shape (n, 2)
        Pixel coordinates (px).
    radius_px : float
        Neighbourhood (px): detections in the square of half-side ``ceil(radius_px)``
        pixels around a detection's pixel are "at the same place".
    fraction : float
        A detection is stationary if more than ``fraction`` of the trial's fields hold a
        detection of the same camera within ``radius_px`` of it.

    Returns
    -------
    ndarray of bool, shape (n,)
        True for stationary (false) detections.
    """
    field = np.asarray(field, dtype=np.int64)
    camera = np.asarray(camera, dtype=np.int64)
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    if not (len(field) == len(camera) == len(uv)):
        raise KisscalError("stationary filter: field, camera and uv must have the same length")
    if not np.all(np.isfinite(uv)):
        raise KisscalError("stationary filter: pixel coordinates contain NaN or inf")
    mask = np.zeros(len(field), dtype=bool)
    if len(field) == 0:
        return mask
    n_fields = len(np.unique(field))
    half = int(np.ceil(radius_px))
    for cam in np.unique(camera):
        rows = np.flatnonzero(camera == cam)
        # the thesis' detections-per-pixel count: an image of counts, summed over the
        # neighbourhood with an integral image, read back at each detection's pixel
        ij = np.rint(uv[rows]).astype(np.int64)
        ij -= ij.min(axis=0) - half
        w, h = ij.max(axis=0) + half + 1
        counts = np.bincount(ij[:, 1] * w + ij[:, 0], minlength=w * h).reshape(h, w)
        integral = np.zeros((h + 1, w + 1), dtype=np.int64)
        integral[1:, 1:] = counts.cumsum(axis=0).cumsum(axis=1)
        u0, u1 = ij[:, 0] - half, ij[:, 0] + half + 1
        v0, v1 = ij[:, 1] - half, ij[:, 1] + half + 1
        near = integral[v1, u1] - integral[v0, u1] - integral[v1, u0] + integral[v0, u0]
        mask[rows] = near > fraction * n_fields
    return mask
