"""summary.json counts a trial's samples by status, how each gap was filled included."""

from __future__ import annotations

from kisscal.io.store import TrialFiles
from kisscal.io.summary import _trial_summary


def test_samples_by_status_and_legacy_filled(tmp_path):
    rows = ["field,track,label,x_mm,y_mm,z_mm,status"]
    status = ["measured"] * 4 + ["filled_rigid"] * 2 + ["filled_pattern", "filled", "predicted"]
    rows += [f"{f},0,A,0,0,0,{s}" for f, s in enumerate(status)]
    files = TrialFiles(tmp_path)
    files.trajectories().write_text("\n".join(rows) + "\n")
    samples = _trial_summary(files)["samples"]
    assert samples == {
        "measured": 4,
        "predicted": 1,
        "filled_spline": 1,  # written as "filled" before contract version 3
        "filled_rigid": 2,
        "filled_pattern": 1,
        "filled": 4,
    }
