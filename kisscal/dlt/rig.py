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
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.dlt.calibrate import calibrate_camera
from kisscal.dlt.check import leave_one_rod_out, triangulate_dlt
from kisscal.dlt.nonlinear import correct_lens
from kisscal.dlt.params import (
    DEFAULT_PARAMS,
    DltParams,
    DltResult,
    Rod,
    RodCheck,
    RodMatch,
    marker_label,
    rod_markers,
)
from kisscal.dlt.rod_geometry import validate_rods
from kisscal.dlt.rods import recognise_rods
from kisscal.dlt.select import MODELS, CameraPoints, ModelChoice, choose_model, staggered_folds
from kisscal.errors import KisscalError, with_context


@dataclass(frozen=True)
class RodCalibration:
    """Calibration of every camera from the rods.

    Attributes
    ----------
    results : dict
        Camera id -> :class:`DltResult`.
    matches : dict
        Camera id -> :class:`RodMatch` of the first frame (blob indices refer to it);
        ``missing`` lists the markers identified in no frame at all.
    marker_uv_px : dict
        Camera id -> (n_rods, n_markers, 2) image coordinates used (averaged over the
        frames where identified), NaN where never identified.
    labels : dict
        Camera id -> names (``"R1.1"``...) of the control points used, in fit order.
    control_xyz_mm, control_uv_px : dict
        Camera id -> the control points used, (M, 3) and (M, 2), in fit order.
    in_sample_mm : ndarray, shape (n_rods, n_markers)
        3D error of each rod marker reconstructed from all calibrated cameras (mm);
        NaN where fewer than two cameras saw it (all NaN with a single camera).
    check : RodCheck or None
        Leave-one-rod-out result (None with fewer than 3 rods or 2 cameras).
    models : ModelChoice or None
        The camera models compared by leaving one rod, then one marker of every rod,
        out at a time (:func:`kisscal.dlt.select.staggered_folds`), when the model was chosen
        from the data (no ``--mdlt`` / ``--refine`` / ``--lens``).
    """

    results: dict[str, DltResult]
    matches: dict[str, RodMatch]
    marker_uv_px: dict[str, NDArray[np.float64]]
    labels: dict[str, tuple[str, ...]]
    control_xyz_mm: dict[str, NDArray[np.float64]]
    control_uv_px: dict[str, NDArray[np.float64]]
    in_sample_mm: NDArray[np.float64]
    check: RodCheck | None
    models: ModelChoice | None = None

    def summary(self) -> dict:
        """JSON-ready figures for ``summary.json`` (rms_px is the Euclidean RMS)."""
        out: dict = {
            "cameras": {
                cam: {
                    "method": r.method,
                    "rms_px": r.rms_px,
                    "n_points": len(r.residuals_px),
                    "missing": list(self.matches[cam].missing),
                    "centre_mm": r.centre_mm.tolist(),
                    "constraint_violation": r.constraint,
                    "constraint_violation_linear": r.constraint_linear,
                }
                for cam, r in self.results.items()
            },
        }
        if np.isfinite(self.in_sample_mm).any():
            out["rods_in_sample_mean_mm"] = float(np.nanmean(self.in_sample_mm))
            out["rods_in_sample_max_mm"] = float(np.nanmax(self.in_sample_mm))
        if self.models is not None:
            out["lens_models"] = self.models.rig_dict()
        if self.check is not None and np.isfinite(self.check.errors_mm).any():
            out["leave_one_rod_out"] = {
                "mean_mm": self.check.overall_mean_mm,
                "max_mm": self.check.overall_max_mm,
                "per_rod": {
                    name: {"mean_mm": float(m), "max_mm": float(x), "n_markers": int(n)}
                    for name, m, x, n in zip(
                        self.check.rod_names,
                        self.check.mean_mm,
                        self.check.max_mm,
                        self.check.n_markers,
                        strict=True,
                    )
                },
            }
        return out


def _frames(blobs: ArrayLike | Sequence[ArrayLike]) -> list[NDArray[np.float64]]:
    if isinstance(blobs, np.ndarray) and blobs.ndim == 2:
        return [blobs]
    return [np.asarray(b, dtype=float).reshape(-1, 2) for b in blobs]


def calibrate_rods(
    blobs_px: Mapping[str, ArrayLike | Sequence[ArrayLike]],
    rods: Sequence[Rod],
    params: DltParams = DEFAULT_PARAMS,
    leave_one_out: bool = True,
    candidates: Sequence[str] = tuple(MODELS),
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
    candidates : sequence of str
        The camera models compared when ``params`` leaves the choice to the data
        (:func:`kisscal.dlt.select.choose_model`).

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
    truth = rod_markers(rods)
    n_markers = truth.shape[1]
    names = [marker_label(r.name, i) for r in rods for i in range(n_markers)]
    results, matches, muvs, labels, cxyz, cuv = {}, {}, {}, {}, {}, {}
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
        never = [
            marker_label(r.name, i)
            for ir, r in enumerate(rods)
            for i in range(len(r.points_mm))
            if not found[ir, i]
        ]
        matches[cam] = replace(matches[cam], missing=tuple(never))
        muvs[cam] = muv
        labels[cam] = tuple(n for n, f in zip(names, found.ravel(), strict=True) if f)
        cxyz[cam], cuv[cam] = truth[found], muv[found]
    choice = None
    if params.selects:
        choice = _choose(muvs, truth, params, candidates)
        params = choice.params(params)
    for cam in muvs:
        results[cam] = _calibrate_or_explain(cxyz[cam], cuv[cam], params, cam, matches[cam])
    cams = list(results)
    in_sample = np.full((len(rods), n_markers), np.nan)
    check = None
    if len(cams) >= 2:  # 3D checks need two cameras (``--camera C`` calibrates one)
        in_sample = in_sample_errors(results, muvs, truth)
        if leave_one_out and len(rods) >= 3:
            check = leave_one_rod_out(np.stack([muvs[c] for c in cams]), rods, params, cams)
    return RodCalibration(results, matches, muvs, labels, cxyz, cuv, in_sample, check, choice)


def in_sample_errors(
    results: Mapping[str, DltResult],
    marker_uv_px: Mapping[str, NDArray[np.float64]],
    truth: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Each rod marker's 3D error (mm), reconstructed by every camera of ``results`` from
    its images ``marker_uv_px``; ``truth``: :func:`~kisscal.dlt.params.rod_markers`."""
    cams = list(results)
    obs = np.stack(
        [correct_lens(results[c].L, results[c].lens, marker_uv_px[c].reshape(-1, 2)) for c in cams]
    )
    xyz, _ = triangulate_dlt(np.array([results[c].L for c in cams]), obs)
    return np.linalg.norm(xyz - truth.reshape(-1, 3), axis=1).reshape(truth.shape[:2])


def _choose(
    muvs: Mapping[str, NDArray[np.float64]],
    truth: NDArray[np.float64],
    params: DltParams,
    candidates: Sequence[str],
) -> ModelChoice:
    """The camera model by two fold designs: one rod out at a time (how the model
    reaches into the corner a missing rod leaves), and one marker of every rod out at a
    time (:func:`kisscal.dlt.select.staggered_folds`: how it does between the rods)."""
    n_rods, n_markers = truth.shape[:2]
    ids = np.arange(n_rods * n_markers)
    points = {}
    for cam, muv in muvs.items():
        found = (np.isfinite(muv).all(axis=-1) & np.isfinite(truth).all(axis=-1)).ravel()
        points[cam] = CameraPoints(
            truth.reshape(-1, 3)[found], muv.reshape(-1, 2)[found], ids[found]
        )
    rod = ids // n_markers
    designs = np.stack([rod, staggered_folds(rod, ids % n_markers, n_markers)])
    return choose_model(points, designs, params, candidates)


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
        rows = zip(match.rod_names, match.blob_index, strict=True)
        absent = [name for name, b in rows if (b < 0).any()]
        raise with_context(
            exc,
            suffix=f"; rod markers not identified: {len(match.missing)} (rods {', '.join(absent)})",
        ) from None
