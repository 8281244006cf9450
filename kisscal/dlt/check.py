"""Quality checks of a calibration: n-camera triangulation and the leave-one-rod-out test.

The triangulation is the least-squares n-camera DLT reconstruction (Küçük 2005,
eqs. 2.14 ff.; Shafiq et al. 2001, section 4) of the reconstruction stage,
:func:`kisscal.dlt.triangulate.triangulate`, called here in the rods' array layout.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.dlt.calibrate import calibrate_camera
from kisscal.dlt.nonlinear import correct_lens
from kisscal.dlt.params import DEFAULT_PARAMS, DltParams, Rod, RodCheck, rod_markers
from kisscal.dlt.triangulate import triangulate
from kisscal.errors import InputError, KisscalError


def triangulate_dlt(
    L: ArrayLike, uv_px: ArrayLike, iterations: int = 2
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Least-squares 3D points from two or more cameras' DLT parameters.

    Each camera seeing a point gives two equations linear in ``(X, Y, Z)``,
    ``(L1 - u L9) X + (L2 - u L10) Y + (L3 - u L11) Z = u - L4`` and the same with
    ``L5..L8`` and ``v``. Rows are then reweighted by the inverse of the projective
    denominator ``L9 X + L10 Y + L11 Z + 1`` so that the minimised residuals are pixel
    distances rather than depth-scaled ones (Woltring & Huiskes' bias argument).

    Parameters
    ----------
    L : array_like, shape (C, 11)
        DLT parameters of the C cameras.
    uv_px : array_like, shape (C, N, 2)
        Image coordinates, NaN where a camera does not see a point.
    iterations : int
        Reweighting passes after the unweighted solve.

    Returns
    -------
    xyz_mm : ndarray, shape (N, 3)
        NaN for points seen by fewer than two cameras or with (nearly) parallel rays.
    n_cameras : ndarray of int, shape (N,)

    Raises
    ------
    KisscalError
        ``L`` not of shape (C, 11) or not finite, or ``uv_px`` not of shape (C, N, 2).

    See Also
    --------
    kisscal.dlt.triangulate.triangulate : the solver used, points-first layout.
    """
    # One method, one implementation: the reconstruction stage's batched solver
    # (same equations and reweighting), which takes points first, cameras second.
    uv = np.asarray(uv_px, dtype=float)
    if uv.ndim != 3:
        raise InputError(f"uv_px must have shape (n_cameras, n_points, 2), got {uv.shape}")
    tri = triangulate(L, np.swapaxes(uv, 0, 1), reweight_iterations=iterations)
    return tri.xyz_mm, tri.n_cameras


def leave_one_rod_out(
    marker_uv_px: ArrayLike,
    rods: Sequence[Rod],
    params: DltParams = DEFAULT_PARAMS,
    cameras: Sequence[str] | None = None,
) -> RodCheck:
    """Calibrate every camera on all rods but one, reconstruct the left-out rod's markers.

    The harsher accuracy figure of the rod calibration: the left-out rod lies at an edge
    of the volume, so its markers are reconstructed by extrapolation from the others.

    Parameters
    ----------
    marker_uv_px : array_like, shape (C, n_rods, n_markers, 2)
        Per camera, the (linearised) image coordinates of every rod marker, NaN where it
        was not identified (see :meth:`RodMatch.marker_uv`).
    rods : sequence of Rod
        The surveyed rods.
    params : DltParams
        Calibration method used for each fold (the same as for the real calibration).
    cameras : sequence of str, optional
        Camera ids for messages.

    Returns
    -------
    RodCheck
        Mean and largest 3D error (mm) per left-out rod. A camera whose remaining rods do
        not determine a DLT (too few or coplanar points) is left out of that fold.
    """
    muv = np.asarray(marker_uv_px, dtype=float)
    n_rods, n_markers = muv.shape[1:3]
    fold = np.repeat(np.arange(n_rods), n_markers).reshape(n_rods, n_markers)
    return RodCheck.of(rods, leave_folds_out(muv, rods, fold, params, cameras))


def leave_folds_out(
    marker_uv_px: ArrayLike,
    rods: Sequence[Rod],
    fold: ArrayLike,
    params: DltParams = DEFAULT_PARAMS,
    cameras: Sequence[str] | None = None,
) -> NDArray[np.float64]:
    """3D error (mm) of every rod marker when each camera is calibrated without its fold.

    Parameters
    ----------
    marker_uv_px : array_like, shape (C, n_rods, n_markers, 2)
        As for :func:`leave_one_rod_out`.
    rods : sequence of Rod
    fold : array_like of int, shape (n_rods, n_markers)
        The fold of each marker: the markers of one fold are left out together and
        reconstructed by cameras calibrated on the others (-1: never left out). A rod's
        index: leave one rod out; every k-th marker of each rod: markers held out
        between calibrated ones, no extrapolation.
    params : DltParams
    cameras : sequence of str, optional
        Camera ids for messages.

    Returns
    -------
    ndarray, shape (n_rods, n_markers)
        NaN where a marker was never left out or not reconstructed (fewer than two
        cameras determined a DLT without its fold, or fewer than two saw it).
    """
    muv = np.asarray(marker_uv_px, dtype=float)
    n_cams, n_rods, n_markers, _ = muv.shape
    fold = np.asarray(fold)
    cameras = list(cameras) if cameras is not None else [f"#{i}" for i in range(n_cams)]
    truth = rod_markers(rods)
    errors = np.full((n_rods, n_markers), np.nan)
    for k in np.unique(fold[fold >= 0]):
        Ls, obs = [], []
        rest, out = fold != k, fold == k
        for ic in range(n_cams):
            uv, xyz = muv[ic][rest], truth[rest]
            keep = np.isfinite(uv).all(axis=1) & np.isfinite(xyz).all(axis=1)
            try:
                result = calibrate_camera(xyz[keep], uv[keep], params, cameras[ic])
            except KisscalError:
                continue
            Ls.append(result.L)
            obs.append(correct_lens(result.L, result.lens, muv[ic][out]))
        if len(Ls) < 2:
            continue
        xyz_rec, _ = triangulate_dlt(np.array(Ls), np.array(obs))
        errors[out] = np.linalg.norm(xyz_rec - truth[out], axis=1)
    return errors
