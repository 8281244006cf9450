"""One camera's calibration from control points: linear DLT, then MDLT and/or refinement."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import rms_px
from kisscal.dlt.camera import decompose_dlt, hatze_violation
from kisscal.dlt.linear import check_control_points, reprojection_residuals, solve_dlt
from kisscal.dlt.nonlinear import correct_lens, refine_dlt, solve_mdlt
from kisscal.dlt.params import DEFAULT_PARAMS, DltParams, DltResult


def calibrate_camera(
    xyz_mm: ArrayLike, uv_px: ArrayLike, params: DltParams = DEFAULT_PARAMS, camera: str = ""
) -> DltResult:
    """Calibrate one camera from control points (Küçük 2005 §2.3; Kolahi 2007 §4; Woltring 1990).

    Steps: linear DLT on normalised coordinates (eqs. 2.10-2.13); with ``params.mdlt`` the
    MDLT (Kolahi eq. 10); with ``params.refine`` or ``params.lens`` the reprojection error
    in pixels is minimised from there (keeping the constraint when ``mdlt``).

    Parameters
    ----------
    xyz_mm : array_like, shape (N, 3)
        Surveyed control points (lab mm).
    uv_px : array_like, shape (N, 2)
        Their linearised image coordinates (pixels).
    params : DltParams
        Method switches and tolerances.
    camera : str
        Camera id, named in error messages.

    Returns
    -------
    DltResult
        ``rms_px`` is sqrt(mean(du^2 + dv^2)) over the N points.
    """
    xyz, uv = check_control_points(xyz_mm, uv_px, params, camera)
    L_linear = solve_dlt(xyz, uv, params, camera)
    L, lens, n_eval = L_linear, None, 0
    if params.mdlt:
        L, n_eval = solve_mdlt(xyz, uv, params, camera, L0=L_linear)
    if params.refine or params.lens:
        L, lens, n_refine = refine_dlt(xyz, uv, L, params, camera)
        n_eval += n_refine
    residuals = reprojection_residuals(L, xyz, correct_lens(L, lens, uv))
    return dlt_result(L, params.method, lens, residuals, hatze_violation(L_linear), n_eval)


def dlt_result(
    L: NDArray[np.float64],
    method: str,
    lens: NDArray[np.float64] | None,
    res: NDArray[np.float64],
    linear: float,
    iterations: int = 0,
) -> DltResult:
    """The :class:`DltResult` of ``L`` with its control points' residuals ``res`` (px):
    their RMS, ``L``'s pinhole and Hatze violation, and ``linear``, the violation of the
    linear solution it started from."""
    K, R, centre = decompose_dlt(L)
    return DltResult(
        L, method, lens, res, rms_px(res), linear, hatze_violation(L), K, R, centre, iterations
    )
