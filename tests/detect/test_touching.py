"""Touching markers split at distance-transform peaks (kisscal.detect.touching)."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.detect import blobs as fl
from kisscal.detect import detect_blobs
from kisscal.detect.groups import group_canvas, group_crops, measure_groups
from kisscal.detect.scan import group_runs
from kisscal.detect.touching import _Ridges, marker_peaks
from tests.detect.conftest import ASPECT, KISS, render


def _cluster(rng: np.random.Generator, n: int = 20) -> tuple[np.ndarray, np.ndarray]:
    """n clusters of three touching markers (a triangle, 2.4-2.8 radii apart) + singles.

    At that spacing the thresholded spots merge (blur and threshold grow them by about a
    pixel), as foot markers do in the replayed walking5 trial.
    """
    gx, gy = np.meshgrid(np.linspace(40, 700, 10), np.linspace(30, 260, 6))
    cells = np.column_stack([gx.ravel(), gy.ravel()])
    centres, radii = [], []
    for c in cells[: 2 * n : 2]:
        r = rng.uniform(3.0, 4.5)
        turn = rng.uniform(0, 2 * np.pi)
        for k in range(3):
            a = turn + k * 2 * np.pi / 3
            spacing = rng.uniform(2.4, 2.8) * r / np.sqrt(3)  # vertex distance
            centres.append(c + [spacing * np.cos(a), spacing * np.sin(a) / ASPECT])
            radii.append(r)
    for c in cells[1 : 2 * n : 2]:
        centres.append(c + 2.0)
        radii.append(rng.uniform(2.5, 4.5))
    return np.array(centres), np.array(radii)


def test_three_touching_markers_give_three_blobs(rng):
    truth, radius = _cluster(rng)
    blobs = detect_blobs(render(truth, radius), KISS).valid_only()
    d = np.hypot(
        (blobs.x_px[:, None] - truth[:, 0]) / radius,
        (blobs.y_px[:, None] - truth[:, 1]) / (radius / ASPECT),
    )
    found = d.min(axis=0) < 0.5
    assert found.mean() >= 0.85  # 0.89 measured; the rest merge with no neck left
    assert len(blobs) <= len(truth)
    assert (blobs.flags & fl.SPLIT_TOUCHING).any()
    # Shafiq et al.'s (2001) tests alone cut a three-marker cluster into two at most
    paper = detect_blobs(render(truth, radius), KISS.replace(split_touching=False))
    d = np.hypot(
        (paper.x_px[:, None] - truth[:, 0]) / radius,
        (paper.y_px[:, None] - truth[:, 1]) / (radius / ASPECT),
    )
    assert (d.min(axis=0) < 0.5).mean() < found.mean()


@pytest.mark.parametrize("stretch", [1.0, 1.4])
def test_one_marker_has_one_peak(stretch):
    yy, xx = np.mgrid[0:15, 0:25]
    crop = ((xx - 12.2) / (6.0 * stretch)) ** 2 + ((yy - 7.1) / (6.0 / ASPECT)) ** 2 <= 1
    peaks = marker_peaks(crop.astype(np.uint8), ASPECT, 1.2)
    assert len(peaks) == 1
    assert abs(peaks[0, 1] - 7.1) < 0.6


def test_two_touching_discs_have_two_peaks_with_their_radii():
    yy, xx = np.mgrid[0:15, 0:40]
    big = ((xx - 12.0) / 7.0) ** 2 + ((yy - 7.0) / (7.0 / ASPECT)) ** 2 <= 1
    small = ((xx - 23.5) / 4.5) ** 2 + ((yy - 7.0) / (4.5 / ASPECT)) ** 2 <= 1
    peaks = marker_peaks((big | small).astype(np.uint8), ASPECT, 1.2)
    assert len(peaks) == 2
    assert np.allclose(sorted(peaks[:, 0]), [12.0, 23.5], atol=1.0)
    assert peaks[0, 2] > peaks[1, 2]  # the larger marker's peak is higher


def test_peaks_of_all_groups_at_once_are_each_group_s_alone():
    """The distance transform, ridges and peaks of every group on one stacked canvas give
    each group what :func:`marker_peaks` gives it alone: the same peaks in the same
    order, their heights to float32 precision (OpenCV's exact transform rounds a few
    values of a large image one unit apart)."""
    rng = np.random.default_rng(5)
    centres = np.column_stack([rng.uniform(20, 730, 400), rng.uniform(10, 280, 400)])
    image = render(centres, rng.uniform(2.5, 6.0, 400))
    runs = group_runs(image >= 40)
    table = measure_groups(runs)
    idx = np.flatnonzero(table.pixels >= 16)
    ridges = _Ridges.of(*group_canvas(runs, table, idx), ASPECT)
    alone = [marker_peaks(c, ASPECT, 1.2) for _, _, _, c in group_crops(runs, table, idx)]
    together = ridges.peaks(np.arange(idx.size), ASPECT, 1.2)
    assert sum(len(p) >= 2 for p in alone) >= 10  # touching pairs are there
    assert [len(p) for p in alone] == [len(p) for p in together]
    a, b = np.concatenate(alone), np.concatenate(together)
    assert np.array_equal(a[:, :2], b[:, :2]) and np.allclose(a[:, 2], b[:, 2], rtol=1e-6)
    # a group with two peaks has two ridges; most single markers have one
    ridges_per_group = np.bincount(ridges.crop, minlength=idx.size)
    assert (ridges_per_group[[len(p) >= 2 for p in alone]] >= 2).all()
    assert (ridges_per_group >= 2).sum() < idx.size / 2


def test_after_a_split_only_the_parts_are_weighed_again(rng, monkeypatch):
    """The window moments after a split: the new parts and their families alone are
    taken again (a third fewer window pixels on the cavity's target images), and the
    blobs are those of weighing every group again."""
    import kisscal.detect.splits as sp

    image = render(*_cluster(rng))
    weighed: list[int] = []  # groups of each call of the window moments
    split: list[int] = []  # groups after each split
    weigh, measure = sp.Spots.moments, sp.measure_groups

    def counted(self, grouping, table):
        weighed.append(len(table))
        return weigh(self, grouping, table)

    def measured(runs):
        split.append(len(table := measure(runs)))
        return table

    monkeypatch.setattr(sp.Spots, "moments", counted)
    monkeypatch.setattr(sp, "measure_groups", measured)
    fast = detect_blobs(image, KISS)
    monkeypatch.undo()
    monkeypatch.setattr(sp, "_moments_after", lambda spots, before, g, t: weigh(spots, g, t))
    full = detect_blobs(image, KISS)
    assert (fast.flags & fl.SPLIT_TOUCHING).astype(bool).sum() >= 30
    assert len(split) >= 1 and len(weighed) == len(split) + 1
    assert all(w < n for w, n in zip(weighed[1:], split, strict=True))  # not every group
    for name in ("x_px", "y_px", "pixels", "valid", "flags"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(full, name))
