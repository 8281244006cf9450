"""Matching: correct correspondences, one marker per blob, overlaps, the two-camera option."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt.model import project
from kisscal.errors import KisscalError
from kisscal.recon.epipolar import camera_centre_mm
from kisscal.recon.match import match_field, match_trial
from kisscal.recon.params import ReconParams

from .rig import make_rig, make_table, random_markers

STRATEGIES = ["triple", "central"]


def _truth_consistency(marker: np.ndarray, truth: np.ndarray, camera: np.ndarray) -> None:
    """Every marker holds blobs of one true marker, at most one per camera."""
    for m in np.unique(marker[marker >= 0]):
        rows = marker == m
        assert len(set(truth[rows])) == 1, "a marker mixes blobs of different true markers"
        assert len(set(camera[rows])) == rows.sum(), "a marker holds two blobs of one camera"


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_match_field_finds_the_true_correspondences(strategy: str) -> None:
    rng = np.random.default_rng(5)
    dlts = make_rig(5)
    xyz = random_markers(rng, 1, 15)[0]
    perms = [rng.permutation(15) for _ in range(6)]
    points = [project(dlts[c], xyz[perms[c]]) + rng.normal(0, 0.05, (15, 2)) for c in range(6)]
    matches = match_field(points, dlts, ReconParams(strategy=strategy))
    assert len(matches) == 15
    for m in matches:
        assert len(m) == 6
        true_ids = {int(perms[c][b]) for c, b in m.items()}
        assert len(true_ids) == 1


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_ghost_blobs_do_not_make_markers_and_blobs_are_used_once(strategy: str) -> None:
    rng = np.random.default_rng(6)
    dlts = make_rig(6)
    xyz = random_markers(rng, 40, 15)
    field, camera, uv, truth, visible = make_table(rng, dlts, xyz, n_noise=3)
    marker = match_trial(field, camera, uv, dlts, ReconParams(strategy=strategy))
    assert not np.any((marker >= 0) & (truth < 0)), "a noise blob ended in a marker"
    _truth_consistency(marker, truth, camera)
    seen3 = visible.sum(axis=2) >= 3
    n_found = sum(len(np.unique(truth[(field == f) & (marker >= 0)])) for f in range(len(xyz)))
    assert n_found >= 0.995 * seen3.sum()


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_an_overlap_blob_serves_one_marker_and_both_markers_survive(strategy: str) -> None:
    rng = np.random.default_rng(7)
    dlts = make_rig(7)
    a = np.array([100.0, 50.0, 900.0])
    ray = a - camera_centre_mm(dlts[0])
    b = a + 60.0 * ray / np.linalg.norm(ray)  # same image place in camera 0: one merged blob
    others = random_markers(rng, 1, 8)[0]
    xyz = np.vstack([a, b, others])
    points, ids = [], []
    for c in range(6):
        keep = np.arange(len(xyz)) if c else np.delete(np.arange(len(xyz)), 1)
        points.append(project(dlts[c], xyz[keep]) + rng.normal(0, 0.05, (len(keep), 2)))
        ids.append(keep)
    matches = match_field(points, dlts, ReconParams(strategy=strategy))
    by_true = {}
    for m in matches:
        # the merged blob (camera 0, blob 0) is an image of both a and b
        true_ids = {int(ids[c][k]) for c, k in m.items() if (c, k) != (0, 0)}
        assert len(true_ids) == 1
        by_true[true_ids.pop()] = m
    assert set(by_true) == set(range(len(xyz)))
    assert (by_true[0].get(0) == 0) != (by_true[1].get(0) == 0), "merged blob used once"
    assert all(len(m) >= 5 for m in matches)


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_two_camera_markers_only_when_allowed(strategy: str) -> None:
    # marker 0 moves along a line; after field 3 only cameras 0 and 3 see it
    rng = np.random.default_rng(8)
    dlts = make_rig(8)
    xyz = np.repeat(random_markers(rng, 1, 4), 8, axis=0)
    xyz[:, 0] += np.arange(8)[:, None] * [12.0, -5.0, 3.0]
    field, camera, uv = [], [], []
    for f in range(8):
        for c in range(6):
            keep = np.arange(4) if c in (0, 3) or f < 4 else np.arange(1, 4)
            field += [f] * len(keep)
            camera += [c] * len(keep)
            uv.append(project(dlts[c], xyz[f, keep]))
    uv = np.concatenate(uv)
    for allow, late in ((False, [6, 6, 6]), (True, [2, 6, 6, 6])):
        params = ReconParams(strategy=strategy, allow_two_camera=allow)
        marker = match_trial(field, camera, uv, dlts, params)
        for f in range(8):
            m = marker[np.asarray(field) == f]
            sizes = sorted(np.unique(m[m >= 0], return_counts=True)[1].tolist())
            assert sizes == ([6, 6, 6, 6] if f < 4 else late)


def test_bad_tables_raise() -> None:
    dlts = make_rig(0)
    with pytest.raises(KisscalError):
        match_trial([0], [7], [[1.0, 2.0]], dlts)
    with pytest.raises(KisscalError):
        match_field([np.zeros((1, 2))], dlts)


def test_extension_with_no_blob_in_reach_leaves_the_triple_alone() -> None:
    # a spare blob far from every projection: extension finds no candidate at all
    dlts = make_rig(9)
    xyz = random_markers(np.random.default_rng(9), 1, 1)[0]
    points = [project(dlts[c], xyz) for c in range(3)] + [np.zeros((0, 2))] * 2
    points.append(project(dlts[5], xyz) + [40.0, 0.0])
    matches = match_field(points, dlts)
    assert matches == [{0: 0, 1: 0, 2: 0}]


def test_residual_limit_tightens_to_the_trials_noise_but_not_below_the_floor() -> None:
    from kisscal.recon.match import residual_limit_px

    p = ReconParams(max_rms_px=1.0, outlier_rms_factor=5.0, outlier_floor_px=0.2)
    assert residual_limit_px(np.array([0.05, 0.06, 0.06, 0.9]), p) == pytest.approx(0.3)
    assert residual_limit_px(np.array([1e-9, 2e-9]), p) == pytest.approx(0.2)
    assert residual_limit_px(np.array([0.4, 0.5, 0.6]), p) == pytest.approx(1.0)
    off = ReconParams(outlier_rms_factor=0.0)
    assert residual_limit_px(np.array([0.05, 0.06]), off) == off.max_rms_px


@pytest.mark.parametrize("strategy", STRATEGIES)
def test_a_blob_wrongly_attached_to_an_occluded_neighbour_is_split_off(strategy: str) -> None:
    # marker b is hidden from camera 5, where marker a's blob lies 1.5 px from b's image:
    # extension attaches it to b; the trial's residual limit must split it off again
    rng = np.random.default_rng(10)
    dlts = make_rig(10)
    xyz = random_markers(rng, 30, 2)
    xyz[:, 1] = xyz[:, 0] + [0.0, 0.0, 60.0]
    fields, cams, uvs, truth = [], [], [], []
    for f in range(30):
        for c in range(6):
            for m in range(2):
                if m == 1 and c == 5:
                    continue
                uv = project(dlts[c], xyz[f, m]) + rng.normal(0, 0.05, 2)
                if m == 0 and c == 5:
                    uv = project(dlts[c], xyz[f, 1]) + [1.5, 0.0]  # near b's image
                fields.append(f)
                cams.append(c)
                uvs.append(uv)
                truth.append(m)
    field, camera, uv, truth = map(np.asarray, (fields, cams, uvs, truth))
    # plenty of clean markers elsewhere set the trial's noise level
    extra = random_markers(rng, 30, 10)
    for f in range(30):
        for c in range(6):
            p = project(dlts[c], extra[f]) + rng.normal(0, 0.05, (10, 2))
            field = np.r_[field, np.full(10, f)]
            camera = np.r_[camera, np.full(10, c)]
            uv = np.vstack([uv, p])
            truth = np.r_[truth, 2 + np.arange(10)]
    marker = match_trial(field, camera, uv, dlts, ReconParams(strategy=strategy))
    for m in np.unique(marker[marker >= 0]):
        assert len(set(truth[marker == m])) == 1
