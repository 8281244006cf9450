"""Synthetic calibration scenes: the wand trial, the L-frame, the target photographs."""

from __future__ import annotations

import numpy as np

from kisscal.synth.cameras import VOLUME_MM, kiss_rig
from kisscal.synth.render import RenderParams
from kisscal.synth.scene import visibility
from kisscal.synth.target import seed_points, target_points, target_rig
from kisscal.synth.wand import AXES_POINTS_MM, render_axes, wand_trial
from kisscal.target.match import is_planar


def test_wand_is_rigid_turns_and_reaches_beyond_the_volume() -> None:
    m = wand_trial(2, 600, 50.0, (0.0, 190.0, 500.0))
    xyz = m.xyz_mm
    assert np.allclose(np.linalg.norm(xyz[:, 2] - xyz[:, 0], axis=1), 500.0)
    assert np.allclose(np.linalg.norm(xyz[:, 1] - xyz[:, 0], axis=1), 190.0)
    d = (xyz[:, 2] - xyz[:, 0]) / 500.0
    assert np.abs(d).max(axis=0).min() > 0.9  # every axis direction is taken up
    lo, hi = np.asarray(VOLUME_MM)
    centre = xyz.mean(axis=1)
    assert (centre[:, :2] < lo[:2]).any() and (centre[:, :2] > hi[:2]).any()
    assert centre[:, 2].min() > 0.0


def test_wand_partial_views_exist_but_most_fields_are_whole() -> None:
    m = wand_trial(3, 300, 50.0)
    vis = visibility(kiss_rig(3)[0], m)
    whole = vis.all(axis=1).mean()
    partial = (vis.any(axis=1) & ~vis.all(axis=1)).mean()
    assert 0.3 < whole < 1.0 and partial > 0.0


def test_axes_frames_show_every_marker_where_the_truth_says() -> None:
    rig = kiss_rig(1)
    frames, truth = render_axes(rig, 0, np.asarray(AXES_POINTS_MM), RenderParams(), 1, 2)
    assert len(frames) == 2 and frames[0].shape == (291, 752)
    for u, v in zip(truth["u_px"], truth["v_px"], strict=True):
        assert frames[0][round(v), round(u)] > 100


def test_target_seeds_are_spread_off_one_plane_of_a_stepped_target() -> None:
    xyz, _ = target_points("stepped")
    cam = target_rig(1)[0]
    uv, picked = seed_points(cam, xyz, np.random.default_rng(0))
    assert len(uv) == 6 and not is_planar(picked)
    assert np.abs(uv - cam.project(picked)).max() < 3.0
