"""The report's per-trajectory fill figures: coverage before/after filling, how each gap
was filled."""

from __future__ import annotations

import numpy as np

from kisscal.report.markers import dense_trajectories, filled_runs, marker_stats
from kisscal.report.page_trials import fill_list


def test_coverage_before_and_after_filling_and_each_fill_named():
    n = 10
    status = ["measured"] * n
    status[2:4] = ["filled_spline"] * 2
    status[5:8] = ["filled_rigid"] * 3
    status[8] = "filled_pattern"
    xyz = np.zeros((n, 3))
    d = dense_trajectories(np.arange(n), np.zeros(n), ["A"] * n, xyz, status)
    (m,) = marker_stats(d)
    assert m.coverage == 1.0
    assert m.coverage_measured == 0.4
    assert (m.filled, m.filled_rigid, m.filled_pattern) == (6, 3, 1)
    assert m.fills == ((2, 2, "spline"), (5, 3, "rigid"), (8, 1, "pattern"))
    assert fill_list(m.fills) == "2+2 spline, 5+3 rigid, 8+1 pattern"
    assert fill_list(()) == "-"


def test_legacy_filled_counts_as_spline():
    status = np.array([1, 3, 3, 1], dtype=np.int8)
    assert filled_runs(status) == ((1, 2, "spline"),)
    d = dense_trajectories(
        [0, 1, 2], [0, 0, 0], ["A"] * 3, np.zeros((3, 3)), ["measured", "filled", "measured"]
    )
    assert marker_stats(d)[0].fills == ((1, 1, "spline"),)
