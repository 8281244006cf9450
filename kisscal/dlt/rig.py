"""Whole-rig calibration from rod images: recognise, calibrate every camera, check.

This is the function a session calls for ``kisscal calibrate``: it takes each camera's
linearised blobs of the rod images (one or more frames), recognises the rods
(:func:`kisscal.dlt.rods.recognise_rods`), calibrates each camera
(:func:`kisscal.dlt.calibrate.calibrate_camera`) and measures the 3D accuracy on the
rods: in-sample (every rod marker reconstructed from every camera, the KISS lab's
figure, Shafiq et al. 2001 §3.3) and leave-one-rod-out (the harsher figure).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.dlt.calibrate import calibrate_camera
from kisscal.dlt.check import leave_one_rod_out, triangulate_dlt
from kisscal.dlt.nonlinear import correct_lens
from kisscal.dlt.params import DEFAULT_PARAMS, DltParams, DltResult, Rod, RodCheck, RodMatch
from kisscal.dlt.rods import recognise_rods, validate_rods
from kisscal.errors import KisscalError


@dataclass(frozen=True)
class RodCalibration:
    """Calibration of every camera from the rods.

    Attributes
    ----------
    results : dict
        Camera id -> :class:`DltResult`.
    matches : dict
        Camera id -> :class:`RodMatch` of the first frame (what was found, what is missing).
    marker_uv_px : dict
        Camera id -> (n_rods, n_markers, 2) image coordinates used (averaged over the
        frames where identified), NaN where never identified.
    labels : dict
        Camera id -> names (``"R1[0]"``...) of the control points used, in fit order.
    in_sample_mm : ndarray, shape (n_rods, n_markers)
        3D error of each rod marker reconstructed from all calibrated cameras (mm).
    check : RodCheck or None
        Leave-one-rod-out result (None when fewer than 3 rods).
    """

    results: dict[str, DltResult]
    matches: dict[str, RodMatch]
    marker_uv_px: dict[str, NDArray[np.float64]]
    labels: dict[str, tuple[str, ...]]
    in_sample_mm: NDArray[np.float64]
    check: RodCheck | None


def _frames(blobs: ArrayLike | Sequence[ArrayLike]) -> list[NDArray[np.float64]]:
    if isinstance(blobs, np.ndarray) and blobs.ndim == 2:
        return [blobs]
    return [np.asarray(b, dtype=float).reshape(-1, 2) for b in blobs]


def calibrate_rods(
    blobs_px: Mapping[str, ArrayLike | Sequence[ArrayLike]],
    rods: Sequence[Rod],
    params: DltParams = DEFAULT_PARAMS,
    leave_one_out: bool = True,
) -> RodCalibration:
    """Recognise the rods in every camera, calibrate each camera, measure 3D errors.

    Parameters
    ----------
    blobs_px : mapping
        Camera id -> linearised blob centroids of its rod image, an (N, 2) array, or a
        sequence of such arrays (several frames of the static rods: each marker's
        position is averaged over the frames in which it was identified).
    rods : sequence of Rod
        From ``[[rods.rod]]`` (:func:`kisscal.dlt.rods.make_rods`).
    params : DltParams
        Calibration method and tolerances.
    leave_one_out : bool
        Also run the leave-one-rod-out check (needs 3 rods or more).

    Returns
    -------
    RodCalibration

    Raises
    ------
    KisscalError
        Non-unique rods, an ambiguous identification, or a camera whose identified
        markers do not determine a DLT (message names the camera and what is missing).
    """
    validate_rods(rods, params)
    n_markers = max(len(r.points_mm) for r in rods)
    truth = np.full((len(rods), n_markers, 3), np.nan)
    for ir, rod in enumerate(rods):
        truth[ir, : len(rod.points_mm)] = rod.points_mm
    names = [f"{r.name}[{i}]" for r in rods for i in range(n_markers)]
    results, matches, muvs, labels = {}, {}, {}, {}
    for cam, blobs in blobs_px.items():
        frames = _frames(blobs)
        per_frame = []
        for k, uv in enumerate(frames):
            m = recognise_rods(uv, rods, params, camera=cam)
            if k == 0:
                matches[cam] = m
            per_frame.append(m.marker_uv(uv))
        with np.errstate(invalid="ignore"):
            stack = np.stack(per_frame)
            seen = np.isfinite(stack).all(axis=-1)
            muv = np.where(
                seen.any(axis=0)[..., None],
                np.nansum(stack, axis=0) / np.maximum(seen.sum(axis=0), 1)[..., None],
                np.nan,
            )
        found = np.isfinite(muv).all(axis=-1) & np.isfinite(truth).all(axis=-1)
        result = _calibrate_or_explain(truth[found], muv[found], params, cam, matches[cam])
        results[cam] = result
        muvs[cam] = muv
        labels[cam] = tuple(n for n, f in zip(names, found.ravel(), strict=True) if f)
    cams = list(results)
    Ls = np.array([results[c].L for c in cams])
    obs = np.stack(
        [correct_lens(results[c].L, results[c].lens, muvs[c].reshape(-1, 2)) for c in cams]
    )
    xyz, _ = triangulate_dlt(Ls, obs)
    in_sample = np.linalg.norm(xyz - truth.reshape(-1, 3), axis=1).reshape(len(rods), n_markers)
    check = None
    if leave_one_out and len(rods) >= 3 and not params.lens:
        check = leave_one_rod_out(np.stack([muvs[c] for c in cams]), rods, params, cams)
    return RodCalibration(results, matches, muvs, labels, in_sample, check)


def _calibrate_or_explain(
    xyz: NDArray[np.float64],
    uv: NDArray[np.float64],
    params: DltParams,
    camera: str,
    match: RodMatch,
) -> DltResult:
    try:
        return calibrate_camera(xyz, uv, params, camera)
    except KisscalError as exc:
        if not match.missing:
            raise
        absent = sorted({m.split("[")[0] for m in match.missing})
        raise KisscalError(
            f"{exc}; rod markers not identified: {len(match.missing)} (rods {', '.join(absent)})"
        ) from None
