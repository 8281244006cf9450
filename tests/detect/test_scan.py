"""Run-length scan and mid-point grouping (Shafiq et al. 2001, section 2.1)."""

from __future__ import annotations

import cv2
import numpy as np

from kisscal.detect.groups import measure_groups
from kisscal.detect.scan import group_runs, scan_runs


def _partition(labels: np.ndarray) -> set[frozenset[int]]:
    return {frozenset(np.flatnonzero(labels == v).tolist()) for v in np.unique(labels)}


def test_runs_cover_exactly_the_white_pixels(rng):
    white = rng.random((40, 60)) < 0.3
    y, x1, x2 = scan_runs(white)
    rebuilt = np.zeros_like(white)
    for yy, a, b in zip(y, x1, x2, strict=True):
        assert not rebuilt[yy, a : b + 1].any()
        rebuilt[yy, a : b + 1] = True
    assert np.array_equal(rebuilt, white)
    # maximal runs: no two runs of a line touch
    same_line = y[1:] == y[:-1]
    assert np.all(x1[1:][same_line] > x2[:-1][same_line] + 1)


def test_empty_image_gives_no_runs():
    assert len(group_runs(np.zeros((5, 7), dtype=bool))) == 0


def test_grouping_matches_8_connected_components(rng):
    for density in (0.1, 0.3, 0.55):
        white = rng.random((50, 80)) < density
        runs = group_runs(white)
        n, lab = cv2.connectedComponents(white.astype(np.uint8), connectivity=8)
        # label of each run's first pixel in OpenCV's labelling
        ours = runs.group
        theirs = lab[runs.y, runs.x1]
        assert _partition(ours) == _partition(theirs)
        assert runs.group.max() + 1 == n - 1


def test_groups_are_numbered_in_scan_order():
    white = np.zeros((10, 10), dtype=bool)
    white[5, 1:3] = white[6, 1:3] = True  # second group by scan order
    white[2, 7:9] = white[3, 7:9] = True  # first
    runs = group_runs(white)
    first = runs.group[np.argmin(runs.y)]
    assert first == 0


def test_closeness_bridges_gaps():
    white = np.zeros((10, 20), dtype=bool)
    white[2, 3:8] = True
    white[4, 3:8] = True  # one empty line between
    white[3, 10:12] = True  # adjacent line, two empty columns right of the others
    assert len(measure_groups(group_runs(white))) == 3
    assert len(measure_groups(group_runs(white, closeness_rows=2))) == 2
    assert len(measure_groups(group_runs(white, closeness_x_px=2.0))) == 1
    assert len(measure_groups(group_runs(white, closeness_x_px=1.0))) == 3


def test_group_measures_match_direct_computation(rng):
    white = rng.random((30, 40)) < 0.35
    runs = group_runs(white)
    table = measure_groups(runs)
    _n, lab = cv2.connectedComponents(white.astype(np.uint8), connectivity=8)
    for i, label in enumerate(table.label):
        cv_label = lab[runs.y[runs.group == label][0], runs.x1[runs.group == label][0]]
        ys, xs = np.nonzero(lab == cv_label)
        assert table.pixels[i] == xs.size
        assert (table.x1[i], table.x2[i], table.y1[i], table.y2[i]) == (
            xs.min(),
            xs.max(),
            ys.min(),
            ys.max(),
        )
        assert np.isclose(table.x_binary[i], xs.mean())
        assert np.isclose(table.y_binary[i], ys.mean())
        assert table.rows[i] == np.unique(ys).size
        top = xs[ys == ys.min()]
        bottom = xs[ys == ys.max()]
        assert (table.top_x1[i], table.top_x2[i]) == (top.min(), top.max())
        assert (table.bottom_x1[i], table.bottom_x2[i]) == (bottom.min(), bottom.max())
