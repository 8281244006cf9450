"""Wand calibration: sparse bundle adjustment of cameras, lenses and wand poses.

Typical use (arrays only; :mod:`kisscal.session.routes.wand` runs it for a session)::

    table = BlobTable.of(blobs_per_camera)                # a wand trial's blobs
    cal = calibrate_on_control(table, start, rods, markers_mm, sizes, ids, "wand01")
    cal = calibrate_wand_alone(table, markers_mm, sizes, ids, "wand01")
    frame = axes_frame(cal.cameras, sizes, ids, axes_blobs, axes_mm, 0.03)

The cameras are :class:`kisscal.camera.Camera` (pinhole + Brown lens). Modules:
:mod:`~kisscal.bundle.model` (projection and its analytic Jacobian),
:mod:`~kisscal.bundle.solve` (sparse Levenberg-Marquardt, Schur complement),
:mod:`~kisscal.bundle.adjust` (the adjustment with outlier passes),
:mod:`~kisscal.bundle.find` (the wand in images and in 3D),
:mod:`~kisscal.bundle.initialise` (cameras from the wand alone),
:mod:`~kisscal.bundle.frame` (the lab frame from an axes object),
:mod:`~kisscal.bundle.wand` (whole-rig pipelines) and :mod:`~kisscal.bundle.quality`
(wand length, per-camera figures, held-out checks).
"""

from kisscal.bundle.adjust import (
    BundleResult,
    ControlPoints,
    WandObservations,
    WandPoses,
    adjust_bundle,
)
from kisscal.bundle.find import find_wand_images, find_wand_points
from kisscal.bundle.frame import recognise_object, similarity
from kisscal.bundle.initialise import start_from_wand
from kisscal.bundle.params import BundleParams
from kisscal.bundle.quality import held_out_lengths, leave_one_group_out, length_figures
from kisscal.bundle.wand import (
    BlobTable,
    WandCalibration,
    axes_frame,
    calibrate_on_control,
    calibrate_wand_alone,
)

__all__ = [
    "BlobTable",
    "BundleParams",
    "BundleResult",
    "ControlPoints",
    "WandCalibration",
    "WandObservations",
    "WandPoses",
    "adjust_bundle",
    "axes_frame",
    "calibrate_on_control",
    "calibrate_wand_alone",
    "find_wand_images",
    "find_wand_points",
    "held_out_lengths",
    "leave_one_group_out",
    "length_figures",
    "recognise_object",
    "similarity",
    "start_from_wand",
]
