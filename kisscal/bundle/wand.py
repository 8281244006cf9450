"""Whole-rig wand calibration on arrays: find the wand, start, adjust, refine.

Two starts, one adjustment:

* :func:`calibrate_on_control` starts from cameras already calibrated (the rods' DLT on
  the grid's linearisation), finds the wand in 3D with them and adjusts cameras, lenses
  and wand poses together with the rods' surveyed markers as fixed control points, which
  keep the lab frame and scale.
* :func:`calibrate_wand_alone` starts from nothing: the wand is found in each image,
  the cameras start from a pair and resection (:mod:`kisscal.bundle.initialise`), a first
  adjustment follows, then the wand is found again in 3D with those cameras (which
  recovers fields with ghosts) and the adjustment is repeated. The frame is then the
  first camera's until :mod:`kisscal.bundle.frame` moves it onto the axes object.

Coordinates throughout are those the lens model acts on: grid-linearised pixels when the
session has a grid, raw pixels otherwise.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from kisscal.bundle.adjust import (
    BundleResult,
    ControlPoints,
    WandObservations,
    WandPoses,
    adjust_bundle,
    centred_offsets,
)
from kisscal.bundle.find import find_wand_images, find_wand_points, pairs_within_fields
from kisscal.bundle.frame import ObjectMatch, recognise_object
from kisscal.bundle.initialise import start_from_wand, wand_poses
from kisscal.bundle.params import DEFAULT_PARAMS, BundleParams
from kisscal.bundle.resect import final_cameras
from kisscal.camera import Camera, camera_linearisation
from kisscal.dlt import DltParams
from kisscal.dlt.params import DEFAULT_PARAMS as DEFAULT_DLT
from kisscal.errors import EstimationFailed, InputError
from kisscal.recon import ReconParams, reconstruct_trial, stationary_mask
from kisscal.rig import Rig


@dataclass(frozen=True)
class BlobTable:
    """A trial's blobs, long format, sorted by field then camera.

    Attributes
    ----------
    field, camera : ndarray of int, shape (n,)
    uv_px : ndarray, shape (n, 2)
        In the coordinates the lens model acts on.
    n_fields : int
    """

    field: NDArray[np.int64]
    camera: NDArray[np.int64]
    uv_px: NDArray[np.float64]
    n_fields: int

    @classmethod
    def of(cls, per_camera: Sequence[Sequence[NDArray[np.float64]]]) -> BlobTable:
        """From each camera's list of per-field (n_f, 2) arrays."""
        fields, cams, uvs = [], [], []
        for c, frames in enumerate(per_camera):
            counts = [len(np.asarray(f).reshape(-1, 2)) for f in frames]
            fields.append(np.repeat(np.arange(len(frames)), counts))
            cams.append(np.full(sum(counts), c))
            uvs.append(
                np.concatenate([np.zeros((0, 2)), *[np.reshape(f, (-1, 2)) for f in frames]])
            )
        field = np.concatenate(fields).astype(np.int64)
        camera = np.concatenate(cams).astype(np.int64)
        order = np.lexsort((camera, field))
        n = max((len(f) for f in per_camera), default=0)
        return cls(field[order], camera[order], np.concatenate(uvs)[order], n)


@dataclass(frozen=True)
class WandCalibration:
    """Cameras and wand of a wand calibration, with the observations they were fitted to.

    Attributes
    ----------
    result : BundleResult
        The final adjustment (cameras, wand poses, residuals, inliers).
    observations : WandObservations
        Wand images used, fields numbered ``0 .. n - 1``.
    fields : ndarray of int
        The trial field of each wand field.
    control : ControlPoints or None
        The rods' markers, when they were used.
    anchor : int or None
        The camera whose pose fixed the frame (wand alone), None with control points.
    resected : tuple of Camera or None
        The cameras as written when they are resected on the adjusted points
        (:mod:`kisscal.bundle.resect`), else None.
    dlt : DltParams
        The DLT settings of that resection (a refit of this calibration resects with
        them too).
    lens_terms : tuple of str or None
        The Brown terms the adjustment estimated when the data chose them among
        ``[wand] lens_terms`` (:func:`kisscal.bundle.terms.fewest_terms`; a refit
        estimates those), None: every one of them.
    markers_mm : tuple of float or None
        The markers ``observations.marker`` indexes when they are not the wand's alone
        (trials' markers adjusted with the wand: :func:`kisscal.bundle.points.with_points`),
        else None. Refits and figures of this calibration use :meth:`markers`.
    """

    result: BundleResult
    observations: WandObservations
    fields: NDArray[np.int64]
    control: ControlPoints | None
    anchor: int | None
    resected: tuple[Camera, ...] | None = None
    dlt: DltParams = DEFAULT_DLT
    lens_terms: tuple[str, ...] | None = None
    markers_mm: tuple[float, ...] | None = None

    def markers(self, wand_mm: Sequence[float]) -> tuple[float, ...]:
        """The markers the observations index: ``markers_mm``, or the wand's ``wand_mm``."""
        return self.markers_mm if self.markers_mm is not None else tuple(wand_mm)

    def refit_params(self, params: BundleParams) -> BundleParams:
        """``params`` with the lens terms this adjustment estimated: a refit of it (held-out
        fields, folds of control points) estimates the same model."""
        return params if self.lens_terms is None else replace(params, lens_terms=self.lens_terms)

    @property
    def cameras(self) -> tuple[Camera, ...]:
        """The adjustment's cameras (lens terms on the coordinates it worked in)."""
        return self.result.cameras

    @property
    def written(self) -> tuple[Camera, ...]:
        """The cameras the route writes and measures with."""
        return self.resected if self.resected is not None else self.result.cameras


def lens_rig(
    cameras: Sequence[Camera], sizes_px: Sequence[tuple[int, int]], ids: Sequence[str]
) -> Rig:
    """A :class:`~kisscal.rig.Rig` of the cameras acting on the lens model's coordinates."""
    out = []
    for cam, size, cid in zip(cameras, sizes_px, ids, strict=True):
        lin = camera_linearisation(cam, size)[0] if np.any(cam.lens) else None
        out.append(Camera.from_dlt(cam.dlt, cid, lin, None, size))
    return Rig(tuple(out))


def wand_in_3d(
    table: BlobTable,
    rig: Rig,
    markers_mm: Sequence[float],
    params: BundleParams = DEFAULT_PARAMS,
) -> tuple[WandObservations, WandPoses, NDArray[np.int64], NDArray[np.float64]]:
    """The wand found among the points a calibrated rig reconstructs from the blobs.

    Returns the wand images of every camera that contributed to a marker (fields
    numbered ``0 .. n - 1``), the wand poses of those fields, their trial fields and the
    end-to-end lengths the rig measured (mm).
    """
    recon = ReconParams(allow_two_camera=True)
    points = reconstruct_trial(table.field, table.camera, undistorted(table, rig), rig.dlts, recon)
    found = find_wand_points(points.field, points.xyz_mm, markers_mm, params.match_tol_mm)
    rows = points.blob_row[found.point]  # (n, k, C)
    f, m, c = np.nonzero(rows >= 0)
    obs = WandObservations(f, c, m, table.uv_px[rows[f, m, c]])
    xyz = points.xyz_mm[found.point]
    s = np.asarray(markers_mm, dtype=float)
    ends = np.linalg.norm(xyz[:, np.argmax(s)] - xyz[:, np.argmin(s)], axis=1)
    return obs, wand_poses(xyz, centred_offsets(markers_mm)), found.field, ends


def measured_lengths(table: BlobTable, rig: Rig) -> NDArray[np.float64]:
    """The largest distance between reconstructed points of each field with two or more (mm).

    What a rig measures of the wand (its end markers are its two farthest points) when
    the wand is not found at its stated length: the diagnosis of a wrong ``markers_mm``.
    """
    recon = ReconParams(allow_two_camera=True)
    points = reconstruct_trial(table.field, table.camera, undistorted(table, rig), rig.dlts, recon)
    i, j = pairs_within_fields(points.field)
    if len(i) == 0:
        return np.zeros(0)
    d = np.linalg.norm(points.xyz_mm[i] - points.xyz_mm[j], axis=1)
    starts = np.r_[0, np.flatnonzero(np.diff(points.field[i])) + 1]
    return np.maximum.reduceat(d, starts)


def undistorted(table: BlobTable, rig: Rig) -> NDArray[np.float64]:
    """The blobs in the coordinates each camera's DLT acts on (its lens undone)."""
    uv = np.empty_like(table.uv_px)
    for c, cam in enumerate(rig):
        rows = table.camera == c
        uv[rows] = cam.undistort_px(table.uv_px[rows])
    return uv


def check_length(
    lengths_mm: NDArray[np.float64],
    markers_mm: Sequence[float],
    tolerance: float,
    by: str,
    min_fields: int,
) -> None:
    """Refuse a wand whose stated length the cameras contradict (beyond ``tolerance``).

    Raises
    ------
    KisscalError
        Naming the stated and the measured length, and how many fields measured it.
    """
    if len(lengths_mm) < min_fields:
        return
    nominal = float(np.ptp(np.asarray(markers_mm, dtype=float)))
    measured = float(np.median(lengths_mm))
    if abs(measured / nominal - 1.0) > tolerance:
        raise InputError(
            f"[wand] markers_mm puts the end markers {nominal:g} mm apart, but {by} "
            f"measures {measured:.1f} mm (median of {len(lengths_mm)} fields, "
            f"{measured / nominal - 1:+.1%}); correct markers_mm"
        )


def _enough(obs: WandObservations, min_fields: int, ids: Sequence[str], trial: str) -> None:
    n = len(np.unique(obs.field))
    if n < min_fields:
        raise EstimationFailed(
            f"wand calibration: the wand was found in two or more cameras at once in {n} "
            f"fields of trial {trial!r}; at least {min_fields} are needed"
        )
    per_cam = np.array([len(np.unique(obs.field[obs.camera == c])) for c in range(len(ids))])
    weak = [f"{ids[c]} ({per_cam[c]})" for c in range(len(ids)) if per_cam[c] < min_fields]
    if weak:
        raise EstimationFailed(
            f"wand calibration: too few wand fields in camera {', '.join(weak)}; at least "
            f"{min_fields} are needed per camera (wave the wand through its whole view)"
        )


def _spread(fields: NDArray[np.int64], most: int) -> NDArray[np.bool_]:
    """At most ``most`` wand fields, evenly spread over the trial."""
    if len(fields) <= most:
        return np.ones(len(fields), dtype=bool)
    keep = np.zeros(len(fields), dtype=bool)
    keep[np.linspace(0, len(fields) - 1, most).round().astype(int)] = True
    return keep


def select_fields(
    obs: WandObservations, wand: WandPoses, fields: NDArray[np.int64], keep: NDArray[np.bool_]
) -> tuple[WandObservations, WandPoses, NDArray[np.int64]]:
    """The wand fields marked by ``keep``, renumbered."""
    new = np.cumsum(keep) - 1
    rows = keep[obs.field]
    o = obs.subset(rows)
    o = WandObservations(new[o.field], o.camera, o.marker, o.uv_px, o.weight)
    return o, WandPoses(wand.centre_mm[keep], wand.direction[keep]), fields[keep]


def zero_skew(cameras: Sequence[Camera], params: BundleParams) -> tuple:
    """The cameras with their skew set to zero, unless ``params.skew`` estimates it."""
    if params.skew:
        return tuple(cameras)
    out = []
    for c in cameras:
        K = c.K.copy()
        K[0, 1] = 0.0
        out.append(Camera(K, c.R, c.t, c.lens))
    return tuple(out)


def found_wand(
    table: BlobTable,
    start: Sequence[Camera],
    markers_mm: Sequence[float],
    sizes_px: Sequence[tuple[int, int]],
    ids: Sequence[str],
    trial: str,
    params: BundleParams = DEFAULT_PARAMS,
) -> tuple[WandObservations, WandPoses, NDArray[np.int64]]:
    """The wand found in 3D by calibrated cameras (at most ``max_fields`` fields, evenly
    spread), its length checked against ``markers_mm``: the images, poses and trial
    fields an adjustment on control points starts from.

    Raises
    ------
    KisscalError
        The cameras measure another length, or too few fields hold the wand.
    """
    rig = lens_rig(start, sizes_px, ids)
    obs, wand, fields, lengths = wand_in_3d(table, rig, markers_mm, params)
    if len(fields) < params.min_fields:  # not at its length: is the length wrong?
        lengths = measured_lengths(table, rig)
    check_length(lengths, markers_mm, params.length_tol, "the rods' calibration", params.min_fields)
    _enough(obs, params.min_fields, ids, trial)
    return select_fields(obs, wand, fields, _spread(fields, params.max_fields))


def calibrate_on_control(
    table: BlobTable,
    start: Sequence[Camera],
    control: ControlPoints,
    markers_mm: Sequence[float],
    sizes_px: Sequence[tuple[int, int]],
    ids: Sequence[str],
    trial: str,
    params: BundleParams = DEFAULT_PARAMS,
    dlt: DltParams = DEFAULT_DLT,
) -> WandCalibration:
    """Wand calibration started from calibrated cameras, with fixed control points.

    Parameters
    ----------
    table : BlobTable
        The wand trial's blobs (grid-linearised pixels).
    start : sequence of Camera
        Starting cameras (the rods' DLT, :meth:`kisscal.camera.Camera.from_dlt`).
    control : ControlPoints
        The rods' markers in the same coordinates.
    markers_mm, sizes_px, ids, trial
        The wand, image sizes, camera ids and the trial's name (for messages).
    params : BundleParams
    dlt : DltParams
        The session's DLT settings, for the cameras resected on the adjusted points
        (:func:`kisscal.bundle.resect.final_cameras`).
    """
    obs, wand, fields = found_wand(table, start, markers_mm, sizes_px, ids, trial, params)
    result = adjust_bundle(
        zero_skew(start, params), obs, markers_mm, wand, control, params, fixed_pose=None
    )
    if params.control_weight == 0.0:  # again, each kind of observation by its own noise
        control = control.weighted(noise_ratio(start, control, result))
        result = adjust_bundle(result.cameras, obs, markers_mm, result.wand, control, params)
    elif params.control_weight != control.weight:
        control = control.weighted(params.control_weight)
        result = adjust_bundle(result.cameras, obs, markers_mm, result.wand, control, params)
    final = final_cameras(result, obs, control, markers_mm, params, dlt)
    resected = final if final is not result.cameras else None
    return WandCalibration(result, obs, fields, control, None, resected, dlt)


def noise_ratio(start: Sequence[Camera], control: ControlPoints, result: BundleResult) -> float:
    """Wand residual variance over control residual variance (at least 1).

    The control points' variance is that of the starting cameras' DLT fits (11
    parameters each, so ``2 n - 11`` degrees of freedom per camera); the wand's that of
    the adjustment's inliers (the wand poses' share of the unknowns is small).
    """
    dof, total = 0.0, 0.0
    for c, cam in enumerate(start):
        rows = control.camera == c
        if rows.sum() < 6:
            continue
        r = control.uv_px[rows] - cam.project(control.xyz_mm[rows])
        total += float(np.sum(r**2))
        dof += 2 * int(rows.sum()) - 11
    wand = result.residuals_px[result.inlier]
    if dof <= 0 or total <= 0 or not len(wand):
        return 1.0
    return max(1.0, float(np.mean(wand**2)) / (total / dof))


def calibrate_wand_alone(
    table: BlobTable,
    markers_mm: Sequence[float],
    sizes_px: Sequence[tuple[int, int]],
    ids: Sequence[str],
    trial: str,
    params: BundleParams = DEFAULT_PARAMS,
    recon: ReconParams | None = None,
) -> WandCalibration:
    """Wand calibration from the wand images alone, in the first placed camera's frame.

    Parameters
    ----------
    table : BlobTable
        The wand trial's blobs (raw pixels).
    markers_mm, sizes_px, ids, trial
        The wand, image sizes, camera ids and the trial's name (for messages).
    params : BundleParams
    recon : ReconParams, optional
        Stationary-blob filter settings (LED rings of facing cameras).
    """
    recon = recon or ReconParams(allow_two_camera=True)
    still = stationary_mask(
        table.field,
        table.camera,
        table.uv_px,
        recon.stationary_radius_px,
        recon.stationary_fraction,
    )
    found = []
    for c in range(len(ids)):
        rows = (table.camera == c) & ~still
        cuts = np.searchsorted(table.field[rows], np.arange(1, table.n_fields))
        per_field = np.split(table.uv_px[rows], cuts)  # one (n_f, 2) array per field
        found.append(find_wand_images(per_field, markers_mm, params))
    start = start_from_wand(found, markers_mm, sizes_px, ids, params.min_fields)
    first = adjust_bundle(
        start.cameras, start.observations, markers_mm, start.wand, None, params, start.anchor
    )
    rig = lens_rig(first.cameras, sizes_px, ids)
    obs, wand, fields, _ = wand_in_3d(table, rig, markers_mm, params)
    _enough(obs, params.min_fields, ids, trial)
    obs, wand, fields = select_fields(obs, wand, fields, _spread(fields, params.max_fields))
    result = adjust_bundle(first.cameras, obs, markers_mm, wand, None, params, start.anchor)
    return WandCalibration(result, obs, fields, None, start.anchor)


@dataclass(frozen=True)
class AxesFrame:
    """The lab frame fixed by the axes object.

    Attributes
    ----------
    match : ObjectMatch
        The object's markers among the reconstructed points, and the rigid motion.
    seen : ndarray of int, shape (C, n)
        1 where a camera's blob went into an object marker's 3D point, else 0.
    """

    match: ObjectMatch
    seen: NDArray[np.int64]

    def cameras(self, cameras: Sequence[Camera]) -> tuple[Camera, ...]:
        """The cameras in the lab frame."""
        return tuple(c.transformed(self.match.rotation, self.match.shift_mm) for c in cameras)


def axes_frame(
    cameras: Sequence[Camera],
    sizes_px: Sequence[tuple[int, int]],
    ids: Sequence[str],
    blobs_px: Sequence[NDArray[np.float64]],
    object_mm: NDArray[np.float64],
    length_tol: float,
) -> AxesFrame:
    """Reconstruct the axes object from each camera's static blobs and fit the lab frame.

    Parameters
    ----------
    cameras : sequence of Camera
        The wand-calibrated cameras (any frame, wand scale).
    sizes_px, ids
        Image sizes and camera ids.
    blobs_px : sequence of (n_c, 2) arrays
        Each camera's blobs of the axes images (averaged over frames), in the lens
        model's coordinates.
    object_mm : ndarray, shape (n, 3)
        ``[axes] points_mm``.
    length_tol : float
        Largest relative disagreement between the object's size and its size as the
        wand-scaled cameras measure it.

    Raises
    ------
    KisscalError
        The object is not found, or its size contradicts the wand's length.
    """
    table = BlobTable.of([[b] for b in blobs_px])
    rig = lens_rig(cameras, sizes_px, ids)
    recon = ReconParams(allow_two_camera=True, stationary_filter=False)
    points = reconstruct_trial(table.field, table.camera, undistorted(table, rig), rig.dlts, recon)
    match = recognise_object(points.xyz_mm, object_mm)
    if abs(match.scale - 1.0) > length_tol:
        raise InputError(
            f"the axes object measures {1 / match.scale:.3f} times its [axes] points_mm with "
            f"cameras scaled by the wand ({(1 / match.scale - 1):+.1%}); the wand's "
            "markers_mm or the axes' points_mm are wrong"
        )
    seen = (points.blob_row[match.index] >= 0).T.astype(np.int64)
    return AxesFrame(match, seen)
