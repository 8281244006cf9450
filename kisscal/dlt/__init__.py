"""DLT calibration: 11-parameter DLT, MDLT, rod recognition, projection, decomposition.

Typical use for one camera (arrays only; reading and writing files is :mod:`kisscal.io`)::

    rods = make_rods([(name, points_mm), ...])          # [[rods.rod]] of session.toml
    match = recognise_rods(uv_px, rods, params, camera)  # linearised blobs of a rod image
    xyz, uv, labels = match.control_points(uv_px, rods)
    result = calibrate_camera(xyz, uv, params, camera)   # DltResult

or for the whole rig at once: ``calibrate_rods({camera: blobs_px, ...}, rods, params)``.
"""

from kisscal._shared import rms_px
from kisscal.dlt.calibrate import calibrate_camera
from kisscal.dlt.camera import compose_dlt, decompose_dlt, hatze_violation
from kisscal.dlt.check import leave_one_rod_out, triangulate_dlt
from kisscal.dlt.linear import reprojection_residuals, solve_dlt
from kisscal.dlt.model import dlt_from_krt, dlt_to_matrix, matrix_to_dlt, project
from kisscal.dlt.nonlinear import correct_lens, refine_dlt, solve_mdlt
from kisscal.dlt.params import (
    DEFAULT_PARAMS,
    DltParams,
    DltResult,
    Rod,
    RodCheck,
    RodMatch,
    marker_label,
)
from kisscal.dlt.rig import RodCalibration, calibrate_rods
from kisscal.dlt.rod_geometry import rod_distinctness, validate_rods
from kisscal.dlt.rods import make_rods, recognise_rods

__all__ = [
    "DEFAULT_PARAMS",
    "DltParams",
    "DltResult",
    "Rod",
    "RodCalibration",
    "RodCheck",
    "RodMatch",
    "calibrate_camera",
    "calibrate_rods",
    "compose_dlt",
    "correct_lens",
    "decompose_dlt",
    "dlt_from_krt",
    "dlt_to_matrix",
    "hatze_violation",
    "leave_one_rod_out",
    "make_rods",
    "marker_label",
    "matrix_to_dlt",
    "project",
    "recognise_rods",
    "refine_dlt",
    "reprojection_residuals",
    "rms_px",
    "rod_distinctness",
    "solve_dlt",
    "solve_mdlt",
    "triangulate_dlt",
    "validate_rods",
]
