"""Removal of stationary false detections (Küçük 2005, 3.3.1).

LEDs of the other cameras and fixed reflections appear at the same image place in nearly
every field, while marker images move. Over a whole trial, a detection is stationary when
detections of the same camera sit within a small neighbourhood of it in more than a set
fraction of the fields; all such detections are removed. The neighbourhood radius absorbs
the few-pixel wander of a stationary spot; keeping it small spares moving markers that
cross the spot.

The test cannot tell a marker that stands still from an LED. A subject holds a marker
still for about a second at most within a movement trial (standing before the first step,
a heel through stance), so at the default fraction of one half the trial must last two
seconds (``ReconParams.stationary_min_s``) before stillness means "not a marker". A shorter
trial (a one-field static target, a 0.9 s throw), or one in which nothing moves (a standing
trial), keeps its detections: the LED rings among them are recognised after matching,
by where they reconstruct (at a camera, or where two lines between cameras cross) and by
where they are seen (at the epipoles, :func:`at_epipoles`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points, n_distinct
from kisscal.dlt.model import camera_centre_mm, project
from kisscal.errors import InputError
from kisscal.recon.params import ReconParams


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

    Examples
    --------
    >>> stationary_mask([0, 1, 2, 0, 1, 2], [0] * 6, [[5, 5]] * 3 + [[20, 5], [40, 5], [60, 5]])
    array([ True,  True,  True, False, False, False])
    """
    field, camera, uv = _check(field, camera, uv)
    mask = np.zeros(len(field), dtype=bool)
    if len(field) == 0:
        return mask
    n_fields = n_distinct(field)
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


def at_epipoles(
    camera: ArrayLike, uv: ArrayLike, dlts: ArrayLike, radius_px: float
) -> NDArray[np.bool_]:
    """Detections within ``radius_px`` of where another camera's centre projects.

    That is where the other camera's LED ring is seen (when that camera faces this one):
    the epipole of the pair. Its ray is the line between the two cameras.

    Parameters
    ----------
    camera : array_like of int, shape (n,)
        Camera (row of ``dlts``) of each detection.
    uv : array_like, shape (n, 2)
        Linearised pixel coordinates.
    dlts : array_like, shape (n_cameras, 11)
    radius_px : float

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    camera = np.asarray(camera, dtype=np.int64)
    uv = as_points(uv, 2, "uv")
    dlts = np.asarray(dlts, dtype=float)
    centres = np.array([camera_centre_mm(L) for L in dlts])
    out = np.zeros(len(camera), dtype=bool)
    for c, L in enumerate(dlts):
        others = np.delete(centres, c, axis=0)
        others = others[others @ L[8:11] + 1.0 > 0]  # on the lab's side: in front
        rows = np.flatnonzero(camera == c)
        if len(others) == 0 or len(rows) == 0:
            continue
        e = project(L, others)
        u, v = uv[rows, 0], uv[rows, 1]
        # the distance to the nearest epipole, as np.linalg.norm sums it, on 1-D arrays
        d = np.min([np.sqrt((u - eu) * (u - eu) + (v - ev) * (v - ev)) for eu, ev in e], axis=0)
        out[rows] = d <= radius_px
    return out


def moving_fields_fraction(field: ArrayLike, still: ArrayLike) -> float:
    """Fraction of a trial's fields that keep a detection the mask does not flag."""
    field = np.asarray(field, dtype=np.int64)
    still = np.asarray(still, dtype=bool)
    if len(field) == 0:
        return 0.0
    return n_distinct(field[~still]) / n_distinct(field)


def _check(
    field: ArrayLike, camera: ArrayLike, uv: ArrayLike
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]]:
    field = np.asarray(field, dtype=np.int64)
    camera = np.asarray(camera, dtype=np.int64)
    uv = as_points(uv, 2, "uv")
    if not (len(field) == len(camera) == len(uv)):
        raise InputError("stationary filter: field, camera and uv must have the same length")
    if not np.all(np.isfinite(uv)):
        raise InputError("stationary filter: pixel coordinates contain NaN or inf")
    return field, camera, uv


def false_detections(
    field: ArrayLike,
    camera: ArrayLike,
    uv: ArrayLike,
    params: ReconParams,
    rate_hz: float,
) -> tuple[NDArray[np.bool_], str]:
    """The stationary false detections of a trial, judged as the trial allows.

    Parameters
    ----------
    field, camera, uv : array_like
        The trial's 2D table (px).
    params : ReconParams
        ``stationary_filter``, ``stationary_radius_px``, ``stationary_fraction``,
        ``stationary_min_s``.
    rate_hz : float
        Field rate of the trial (Hz).

    Returns
    -------
    mask : ndarray of bool, shape (n,)
        Detections to remove.
    test : str
        ``"motion"``: the stationary detections (Küçük 2005, 3.3.1); ``"short"``: none,
        because the trial is shorter than ``stationary_min_s`` or the filter would leave
        moving detections in fewer than half of its fields (nothing moves: stillness does
        not tell markers from LEDs); ``"off"``: none, by request.
    """
    field, camera, uv = _check(field, camera, uv)
    if not params.stationary_filter:
        return np.zeros(len(field), dtype=bool), "off"
    still = stationary_mask(
        field, camera, uv, params.stationary_radius_px, params.stationary_fraction
    )
    long_enough = n_distinct(field) >= params.stationary_min_s * rate_hz
    if long_enough and moving_fields_fraction(field, still) >= 0.5:
        return still, "motion"
    return np.zeros(len(field), dtype=bool), "short"
