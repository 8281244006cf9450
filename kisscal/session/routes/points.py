"""Control points given per camera (``[calibration] points``): one DLT each.

For a lab whose calibration object is not the seeds' rods: a frame of known markers or a
digitised target, given as ``u_px,v_px,x_mm,y_mm,z_mm`` rows per camera (raw pixels).
"""

from __future__ import annotations

from kisscal.dlt import DltResult, calibrate_camera
from kisscal.grid import apply_linearisation
from kisscal.io.dltfiles import read_control_points_csv, write_dlt_json
from kisscal.session.inputs import out_dir
from kisscal.session.routes import RouteInputs


def calibrate_from_points(inputs: RouteInputs) -> dict[str, DltResult]:
    """Every camera's DLT from its control-point file."""
    config = inputs.config
    assert config.calibration is not None
    summary = {}
    for cam in inputs.cameras:
        path = config.root / config.calibration.points.replace("{camera}", cam.id)
        uv_raw, xyz, labels = read_control_points_csv(path)
        uv = apply_linearisation(inputs.linearisations[cam.id], uv_raw)
        res = calibrate_camera(xyz, uv, inputs.params.dlt, cam.id)
        write_dlt_json(
            out_dir(inputs.root) / "dlt" / f"{cam.id}.json", cam.id, res, xyz, uv, labels
        )
        summary[cam.id] = res
        inputs.echo(
            f"  calibrate {cam.id}: {res.method}, {len(xyz)} control points, "
            f"rms {res.rms_px:.3f} px"
        )
    return summary
