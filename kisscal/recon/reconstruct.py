"""A whole trial from linearised 2D blobs to 3D points: filter, match, triangulate."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.errors import KisscalError
from kisscal.recon.group import triangulate_markers
from kisscal.recon.match import _check_table, match_trial
from kisscal.recon.params import DEFAULT_PARAMS, ReconParams
from kisscal.recon.stationary import false_detections


@dataclass(frozen=True)
class Points3D:
    """3D points of a trial, one per reconstructed marker per field.

    Attributes
    ----------
    field : ndarray of int, shape (n_points,)
        Field index of each point (ascending).
    xyz_mm : ndarray, shape (n_points, 3)
        Lab coordinates (mm).
    n_cameras : ndarray of int, shape (n_points,)
        Cameras whose blobs formed the point.
    rms_px : ndarray, shape (n_points,)
        Reprojection RMS over those blobs, ``sqrt(mean(du^2 + dv^2))`` (px).
    blob_row : ndarray of int, shape (n_points, n_cameras_total)
        For each camera, the row of the input 2D table that the point used, -1 if none.
    marker : ndarray of int, shape (n_blobs,)
        For each input row, the point (row of this table) it ended in, -1 if unmatched.
    stationary : ndarray of bool, shape (n_blobs,)
        Input rows removed as stationary false detections.
    stationary_test : str
        How they were judged (:func:`kisscal.recon.stationary.false_detections`):
        ``"motion"``, ``"short"`` (a trial too short or too still to judge by motion: none
        removed) or ``"off"``.
    """

    field: NDArray[np.int64]
    xyz_mm: NDArray[np.float64]
    n_cameras: NDArray[np.int64]
    rms_px: NDArray[np.float64]
    blob_row: NDArray[np.int64]
    marker: NDArray[np.int64]
    stationary: NDArray[np.bool_]
    stationary_test: str = "motion"

    def __len__(self) -> int:
        return len(self.field)

    def summary(self) -> dict[str, float | int | list[int]]:
        """Counts and residuals for ``summary.json``.

        Returns
        -------
        dict
            ``points``, ``fields_with_points``, ``blobs``, ``blobs_used``,
            ``blobs_stationary``, ``blobs_unmatched``, ``rms_px_median``, ``rms_px_max``
            and ``points_by_n_cameras`` (index = number of cameras).
        """
        used = int((self.marker >= 0).sum())
        rms = self.rms_px[np.isfinite(self.rms_px)]
        return {
            "points": len(self),
            "fields_with_points": len(np.unique(self.field)),
            "blobs": len(self.marker),
            "blobs_used": used,
            "blobs_stationary": int(self.stationary.sum()),
            "blobs_unmatched": len(self.marker) - used - int(self.stationary.sum()),
            "rms_px_median": float(np.median(rms)) if len(rms) else float("nan"),
            "rms_px_max": float(rms.max()) if len(rms) else float("nan"),
            "points_by_n_cameras": np.bincount(
                self.n_cameras, minlength=self.blob_row.shape[1] + 1
            ).tolist(),
        }


def points_from_markers(
    marker: NDArray[np.int64],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    reweight_iterations: int,
    stationary: NDArray[np.bool_] | None = None,
    stationary_test: str = "off",
) -> Points3D:
    """Triangulate every marker (ids 0..m-1 in field order) from all its blobs."""
    n_cam = len(dlts)
    rows = np.flatnonzero(marker >= 0)
    m = int(marker.max()) + 1 if len(rows) else 0
    tri = triangulate_markers(marker, camera, uv, dlts, reweight_iterations)
    blob_row = np.full((m, n_cam), -1, dtype=np.int64)
    blob_row[marker[rows], camera[rows]] = rows
    pfield = np.zeros(m, dtype=np.int64)
    pfield[marker[rows]] = field[rows]
    if stationary is None:
        stationary = np.zeros(len(marker), dtype=bool)
    return Points3D(
        pfield,
        tri.xyz_mm,
        tri.n_cameras[:m].astype(np.int64),
        tri.rms_px,
        blob_row,
        marker,
        stationary,
        stationary_test,
    )


def reconstruct_trial(
    field: ArrayLike,
    camera: ArrayLike,
    uv: ArrayLike,
    dlts: ArrayLike,
    params: ReconParams = DEFAULT_PARAMS,
    rate_hz: float = 50.0,
) -> Points3D:
    """Reconstruct the 3D points of a trial from its linearised 2D blobs.

    Steps: stationary false detections removed per camera over the whole trial (Küçük 2005,
    3.3.1; if ``params.stationary_filter`` and the trial is long enough and moves), blobs
    matched across cameras with ``params.strategy`` (3.3.4-3.3.5 or Shafiq et al. 2001,
    4.1) and then in pairs (:mod:`kisscal.recon.pairs`), 3D point groups united (3.3.7),
    each marker triangulated from all its blobs by least squares (Shafiq eq. 10) plus
    reweighted steps (Woltring & Huiskes 1990), markers over the trial's residual limit
    split or dropped, and the blobs this frees matched once more; points at a camera (its
    LED ring seen by the others) dropped.

    Parameters
    ----------
    field, camera : array_like of int, shape (n,)
        Field and camera index (row of ``dlts``) of each blob.
    uv : array_like, shape (n, 2)
        Linearised pixel coordinates of each blob.
    dlts : array_like, shape (n_cameras, 11)
        DLT parameters mapping lab mm to linearised px.
    params : ReconParams
    rate_hz : float
        Field rate (Hz), to judge whether the trial is long enough for the stationary
        filter (the KISS cameras' 50 Hz by default).

    Returns
    -------
    Points3D
    """
    dlts = np.asarray(dlts, dtype=float)
    if dlts.ndim != 2 or dlts.shape[1] != 11 or len(dlts) < 2:
        raise KisscalError(f"reconstruction needs >= 2 cameras' DLT (n, 11), got {dlts.shape}")
    if not np.all(np.isfinite(dlts)):
        bad = sorted({int(k) for k in np.nonzero(~np.isfinite(dlts))[0]})
        raise KisscalError(f"reconstruction: DLT parameters of camera index {bad} are not finite")
    field, camera, uv = _check_table(field, camera, uv, len(dlts))
    still, test = false_detections(field, camera, uv, params, rate_hz)
    keep = np.flatnonzero(~still)
    marker = np.full(len(field), -1, dtype=np.int64)
    marker[keep] = match_trial(field[keep], camera[keep], uv[keep], dlts, params)
    return points_from_markers(
        marker, field, camera, uv, dlts, params.reweight_iterations, still, test
    )
