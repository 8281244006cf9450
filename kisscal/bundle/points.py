"""Lens terms fitted on the rods and a trial's markers together (issue 25).

The rods' 24 surveyed markers fix the lab frame and scale but hold a lens model only
between the rods, and cannot tell which model extrapolates. A trial's markers seen by
three cameras or more are unknown points, yet every one of them constrains the cameras
(their rays must meet): a bundle adjustment of the cameras, their lens terms and the
points, with the rods' markers as fixed control points (Triggs et al. 2000; the
self-calibration of photogrammetry, Fraser 1997), lets thousands of rays spread over the
volume decide the lens terms instead of a choice among models on the rods alone. It is
the wand route's adjustment (:func:`kisscal.bundle.wand.calibrate_on_control`) with each
trial marker a one-marker wand: a free 3D point. With a wand trial too
(:func:`calibrate_on_wand_and_points`), the wand's fields and the trials' markers enter
one adjustment: the wand's rigid length adds scale and the volume's middle, the trials'
markers the rays of the whole session (on a four-camera rig they are what fixes the lens
terms; issue 25).

References
----------
Triggs, B., McLauchlan, P. F., Hartley, R. I., & Fitzgibbon, A. W. (2000). Bundle
adjustment - a modern synthesis. Vision Algorithms: Theory and Practice, LNCS 1883.
Fraser, C. S. (1997). Digital camera self-calibration. ISPRS Journal of Photogrammetry
and Remote Sensing 52, 149-159.
Förstner, W. (1979). Ein Verfahren zur Schätzung von Varianz- und Kovarianzkomponenten.
Allgemeine Vermessungs-Nachrichten 86, 446-453.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kisscal.bundle.adjust import (
    BundleResult,
    ControlPoints,
    WandObservations,
    WandPoses,
    adjust_bundle,
    variance_components,
)
from kisscal.bundle.params import DEFAULT_PARAMS, BundleParams
from kisscal.bundle.resect import final_cameras
from kisscal.bundle.terms import fewest_terms
from kisscal.bundle.wand import (
    BlobTable,
    WandCalibration,
    found_wand,
    lens_rig,
    noise_ratio,
    undistorted,
    zero_skew,
)
from kisscal.camera import Camera
from kisscal.dlt import DltParams
from kisscal.dlt.params import DEFAULT_PARAMS as DEFAULT_DLT
from kisscal.errors import EstimationFailed
from kisscal.recon import ReconParams, reconstruct_trial

#: Reweighings of the control points at most, and the ratio of two weights in a row
#: below which the weight has settled.
HELMERT_PASSES = 4
HELMERT_SETTLED = 1.1

#: A free point is a wand of one marker at its centre (its direction is then unused).
POINT = (0.0,)

#: A trial's markers as one-marker wands: their images and starting points.
TrialPoints = tuple[WandObservations, WandPoses]


def trial_points(
    table: BlobTable,
    cameras: Sequence[Camera],
    sizes_px: Sequence[tuple[int, int]],
    min_cameras: int,
    most: int,
) -> TrialPoints:
    """The markers a rig reconstructs from a trial's blobs with ``min_cameras`` or more
    cameras (at most ``most``, evenly spread over the trial), as one-marker wands."""
    rig = lens_rig(cameras, sizes_px, [f"c{k}" for k in range(len(cameras))])
    recon = ReconParams(allow_two_camera=False)
    points = reconstruct_trial(table.field, table.camera, undistorted(table, rig), rig.dlts, recon)
    rows = points.blob_row
    keep = np.flatnonzero((rows >= 0).sum(axis=1) >= min_cameras)
    if len(keep) > most:
        keep = keep[np.linspace(0, len(keep) - 1, most).round().astype(int)]
    rows = rows[keep]
    p, c = np.nonzero(rows >= 0)
    obs = WandObservations(p, c, np.zeros(len(p), np.int64), table.uv_px[rows[p, c]])
    direction = np.tile([0.0, 0.0, 1.0], (len(keep), 1))
    return obs, WandPoses(points.xyz_mm[keep], direction)


def calibrate_on_points(
    table: BlobTable,
    start: Sequence[Camera],
    control: ControlPoints,
    sizes_px: Sequence[tuple[int, int]],
    params: BundleParams = DEFAULT_PARAMS,
    dlt: DltParams = DEFAULT_DLT,
    min_cameras: int = 3,
    weight_factor: float = 1.0,
    markers: TrialPoints | None = None,
) -> WandCalibration:
    """Cameras and lens terms adjusted to a trial's markers and fixed control points.

    Parameters
    ----------
    table : BlobTable
        The trials' blobs (grid-linearised pixels), fields of different trials apart.
    start : sequence of Camera
        Starting cameras (the rods' DLT, :meth:`kisscal.camera.Camera.from_dlt`).
    control : ControlPoints
        The rods' markers in the same coordinates; they fix the frame and scale.
    sizes_px : sequence of (int, int)
        Each camera's image size.
    params : BundleParams
        Lens terms (those beyond the first kept only where the markers prefer them,
        :func:`kisscal.bundle.terms.fewest_terms`), loss, outliers, ``max_fields`` (here
        the most points used),
        ``control_weight`` (0: the rods' and the points' noise variance ratio times
        ``weight_factor``).
    dlt : DltParams
        The session's DLT settings, for the cameras resected on the adjusted points.
    min_cameras : int
        Cameras a marker needs to be used (two rays only meet in a point, whatever the
        lens).
    weight_factor : float
        With ``control_weight`` 0, the estimated noise variance ratio is multiplied by
        this before it weighs the control points.
    markers : (WandObservations, WandPoses), optional
        :func:`trial_points` of ``table`` and ``start`` already made (the same
        ``min_cameras`` and ``params.max_fields``); None: made here.

    Raises
    ------
    KisscalError
        Fewer than ``params.min_fields`` markers seen by ``min_cameras`` cameras.
    """
    obs, points = markers or trial_points(table, start, sizes_px, min_cameras, params.max_fields)
    if len(points.centre_mm) < params.min_fields:
        raise EstimationFailed(
            f"trial bundle: {len(points.centre_mm)} markers seen by {min_cameras} cameras "
            f"or more; at least {params.min_fields} are needed"
        )
    fields = np.arange(len(points.centre_mm))
    return _weighed_adjustment(
        start, obs, POINT, points, fields, control, params, dlt, weight_factor
    )


def _weighed_adjustment(
    start: Sequence[Camera],
    obs: WandObservations,
    markers_mm: tuple[float, ...],
    poses: WandPoses,
    fields: NDArray[np.int64],
    control: ControlPoints,
    params: BundleParams,
    dlt: DltParams,
    weight_factor: float,
    group: NDArray[np.int64] | None = None,
    rods_per_point: float = 0.0,
) -> WandCalibration:
    """Adjust, weigh the control points by the two kinds' noise, adjust again, keep the
    lens terms the observations show, and resect (both routes of this module). With
    ``group`` (each observation's kind), every kind and the control points are then
    weighed by their variance components (:func:`_helmert`, ``rods_per_point``) before
    the lens terms are chosen."""
    result = adjust_bundle(zero_skew(start, params), obs, markers_mm, poses, control, params)
    # again, each kind of observation by its own noise (or the weight given)
    weight = params.control_weight or weight_factor * noise_ratio(start, control, result)
    control = control.weighted(weight)
    result = adjust_bundle(result.cameras, obs, markers_mm, result.wand, control, params)
    if group is not None and not params.control_weight:
        result, obs, control = _helmert(
            result, obs, markers_mm, control, params, group, rods_per_point
        )
    # the terms beyond the first only where the markers show them (not the rods alone)
    result, params = fewest_terms(result, obs, markers_mm, control, params)
    final = final_cameras(result, obs, control, markers_mm, params, dlt)
    resected = final if final is not result.cameras else None
    markers = None if markers_mm == POINT else markers_mm
    return WandCalibration(
        result, obs, fields, control, None, resected, dlt, params.lens_terms, markers
    )


def _helmert(
    result: BundleResult,
    obs: WandObservations,
    markers_mm: tuple[float, ...],
    control: ControlPoints,
    params: BundleParams,
    group: NDArray[np.int64],
    rods_per_point: float = 0.0,
) -> tuple[BundleResult, WandObservations, ControlPoints]:
    """Each kind of observation (``group``, and the control points) reweighed by the
    inverse of the noise variance the adjustment's residuals show, relative to the first
    kind's, and adjusted again, until the weights settle (Helmert's variance components,
    Förstner 1979). With ``rods_per_point``, the control points weigh that many times an
    image of the last kind (the trials' markers) instead of their own component."""
    for _ in range(HELMERT_PASSES):
        kinds, ctrl = variance_components(result, obs, markers_mm, control, group, params)
        if not (np.all(np.isfinite(kinds) & (kinds > 0)) and np.isfinite(ctrl) and ctrl > 0):
            break
        new = np.r_[kinds[0] / kinds, kinds[0] / ctrl]
        if rods_per_point:
            new[-1] = new[-2] * rods_per_point
        old = np.r_[_kind_weights(obs, group, len(kinds)), control.weight]
        obs = obs.weighted((kinds[0] / kinds)[group])
        control = control.weighted(float(new[-1]))
        result = adjust_bundle(result.cameras, obs, markers_mm, result.wand, control, params)
        if np.all(np.abs(np.log(new / old)) < np.log(HELMERT_SETTLED)):
            break
    return result, obs, control


def _kind_weights(obs: WandObservations, group: NDArray[np.int64], n: int) -> NDArray:
    """The weight each kind of observation has now (1 before any)."""
    if obs.weight is None:
        return np.ones(n)
    return np.array([obs.weight[group == k][0] for k in range(n)])


def trial_markers_weight(cal: WandCalibration) -> float:
    """The weight of a trial marker's image against a wand image's in ``cal`` (1 when
    the two kinds were not weighed apart)."""
    obs = cal.observations
    points = cal.fields[obs.field] < 0
    if obs.weight is None or points.all() or not points.any():
        return 1.0
    return float(np.median(obs.weight[points]) / np.median(obs.weight[~points]))


def with_points(markers_mm: Sequence[float]) -> tuple[tuple[float, ...], int]:
    """The wand's markers and a free point's: one more marker at the wand's centre (its
    offset along the wand is 0, so a field of that marker alone is a free 3D point, as
    :data:`POINT`), and its index. The end markers, hence the wand's length and centre,
    are unchanged."""
    s = tuple(float(m) for m in markers_mm)
    return (*s, 0.5 * (min(s) + max(s))), len(s)


def calibrate_on_wand_and_points(
    wand_table: BlobTable,
    trials: BlobTable,
    start: Sequence[Camera],
    control: ControlPoints,
    wand: tuple[Sequence[float], Sequence[str], str],
    sizes_px: Sequence[tuple[int, int]],
    params: BundleParams = DEFAULT_PARAMS,
    dlt: DltParams = DEFAULT_DLT,
    weight_factor: float = 1.0,
    markers: TrialPoints | None = None,
    rods_per_point: float = 0.0,
) -> WandCalibration:
    """Cameras and lens terms adjusted to a wand trial, other trials' markers and fixed
    control points together.

    The wand is found as :func:`kisscal.bundle.wand.calibrate_on_control` finds it, the
    trials' markers seen by three cameras or more as :func:`calibrate_on_points` finds
    them; one adjustment holds both (a trial marker is a field of the centre marker of
    :func:`with_points`). The control points are first weighed as
    :func:`calibrate_on_points` weighs them; then the control points, the wand's images
    and the trials' markers are each weighed by the inverse of the noise variance their
    residuals show (Helmert's variance components, Förstner 1979): a waved wand's images
    are noisier than a walking subject's markers (issue 25: a trial marker weighs 1.7 to
    41 times a wand image on the synthetic rigs), and the rods' residuals hold what the
    lens model misses at their markers as well as their noise.

    Parameters
    ----------
    wand_table, trials : BlobTable
        The wand trial's blobs and the other trials' (grid-linearised pixels).
    start : sequence of Camera
        Starting cameras (the rods' DLT).
    control : ControlPoints
        The rods' markers; they fix the frame and scale.
    wand : (markers_mm, ids, trial)
        The wand's markers, the camera ids and the wand trial's name (for messages).
    sizes_px : sequence of (int, int)
    params : BundleParams
        As :func:`calibrate_on_points` (``max_fields`` caps the wand fields and the
        trials' markers each).
    dlt : DltParams
    weight_factor : float
        With ``control_weight`` 0, times the estimated noise variance ratio (the start of
        the variance components).
    markers : (WandObservations, WandPoses), optional
        :func:`trial_points` of ``trials`` and ``start`` already made (three cameras,
        ``params.max_fields``): those :func:`calibrate_on_points` adjusted; None: made
        here.
    rods_per_point : float
        The control points' weight against a trial marker's image (0: their own variance
        component). The rods route's (:func:`calibrate_on_points`' ``control.weight``)
        holds the lab frame the rods alone fix as that route does: the rods' residuals
        hold what the lens model misses at their markers, so their own component weighs
        them some ten times lower against the trials' markers (issue 25: synthetic kiss
        rig, seed 73, 0.0162 mm inside the volume, the rods route 0.0161; weighed as the
        rods route weighs them, 0.0125 mm; on seed 71 the other way, 0.0134 against
        0.0180: the wand route keeps the lower leave-one-rod-out).

    Returns
    -------
    WandCalibration
        Its ``markers_mm`` those of :func:`with_points`; the trials' markers have trial
        field -1 in ``fields``.
    """
    markers_mm, ids, trial = wand
    obs, poses, fields = found_wand(wand_table, start, markers_mm, sizes_px, ids, trial, params)
    p_obs, points = markers or trial_points(trials, start, sizes_px, 3, params.max_fields)
    markers, centre = with_points(markers_mm)
    n = len(fields)
    obs = WandObservations(
        np.r_[obs.field, p_obs.field + n],
        np.r_[obs.camera, p_obs.camera],
        np.r_[obs.marker, np.full(len(p_obs), centre)],
        np.concatenate([obs.uv_px, p_obs.uv_px]),
    )
    poses = WandPoses(
        np.concatenate([poses.centre_mm, points.centre_mm]),
        np.concatenate([poses.direction, points.direction]),
    )
    fields = np.r_[fields, np.full(len(points.centre_mm), -1)].astype(np.int64)
    # the wand's images and the trials' markers' are two kinds, each with its own noise
    kinds = (obs.marker == centre).astype(np.int64)
    return _weighed_adjustment(
        start,
        obs,
        markers,
        poses,
        fields,
        control,
        params,
        dlt,
        weight_factor,
        kinds,
        rods_per_point,
    )
