"""DLT figures: built without pyplot, drawable, showing what they say."""

from __future__ import annotations

import numpy as np

from kisscal.dlt import calibrate_camera, project
from kisscal.report.dlt import CameraResiduals, residual_figure, rig_figure
from tests.dlt.conftest import rod_xyz


def test_residual_and_rig_figures(rig, tmp_path):
    xyz = rod_xyz(rig)
    rng = np.random.default_rng(0)
    cams, results = {}, {}
    for i in range(6):
        uv = project(rig.L[i], xyz) + rng.normal(0, 0.05, (24, 2))
        r = calibrate_camera(xyz, uv)
        results[f"cam{i + 1}"] = r
        cams[f"cam{i + 1}"] = CameraResiduals(uv, r.residuals_px, (752, 291), r.rms_px)
    fig = residual_figure(cams)
    assert len(fig.axes) == 6
    assert "rms" in fig.axes[0].get_title() and fig.axes[0].get_ylim()[0] > 291  # y down
    fig.savefig(tmp_path / "residuals.png", dpi=60)
    rods = [(r.name, r.points_mm) for r in rig.rods]
    fig3 = rig_figure(
        {c: r.centre_mm for c, r in results.items()},
        rods,
        rotations={c: r.R for c, r in results.items()},
        reconstructed_mm=xyz,
    )
    fig3.savefig(tmp_path / "rig.png", dpi=60)
    assert (tmp_path / "rig.png").stat().st_size > 1000
    assert (tmp_path / "residuals.png").stat().st_size > 1000
