"""Two-camera pairs judged again after deblending (:mod:`kisscal.recon.late`)."""

from __future__ import annotations

import numpy as np

from kisscal.dlt.model import project
from kisscal.recon import ReconParams
from kisscal.recon.deblend import MergeScene
from kisscal.recon.late import late_pairs

from .rig import make_rig


def _scene(seed: int) -> tuple[MergeScene, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Marker A walks 15 fields; its points are known for fields 0-9 (a trajectory) and
    its blobs in cameras 0 and 1 are free in fields 10-14. Marker C, 600 mm away, has free
    blobs in cameras 0 and 1 in fields 3-7 and no point anywhere (a piece that supports
    only itself); a lone pair of free blobs at field 12 is the crossing of nothing known."""
    rng = np.random.default_rng(seed)
    dlts = make_rig(seed, n_cameras=3)
    f = np.arange(15)
    a = np.array([-300.0, 0.0, 900.0]) + f[:, None] * [12.0, 2.0, 0.0]
    c = a + [0.0, 600.0, 300.0]
    ghost = np.array([400.0, -300.0, 1500.0])
    rows = [(k, cam, a[k]) for k in range(10, 15) for cam in (0, 1)]
    rows += [(k, cam, c[k]) for k in range(3, 8) for cam in (0, 1)]
    rows += [(12, cam, ghost) for cam in (0, 1)]
    field = np.array([r[0] for r in rows])
    camera = np.array([r[1] for r in rows])
    uv = np.array([project(dlts[r[1]], r[2][None])[0] for r in rows])
    uv += rng.normal(0.0, 0.05, uv.shape)
    params = ReconParams()
    scene = MergeScene(field, camera, uv, np.ones(len(field), bool), dlts, params, 0.3)
    return scene, f[:10], a[:10], a, c


def test_free_pairs_that_continue_a_trajectory_are_taken() -> None:
    for seed in (0, 1, 2):
        scene, p_field, p_xyz, a, _ = _scene(seed)
        marker = np.full(len(scene.field), -1)
        new = late_pairs(scene, marker, p_field, p_xyz)
        on_a = np.linalg.norm(new.xyz_mm - a[new.field], axis=1) < 2.0
        # A's five free fields continue its trajectory; nothing else is made
        assert sorted(new.field[on_a].tolist()) == [10, 11, 12, 13, 14]
        assert on_a.all()


def test_nothing_without_a_trajectory_to_continue() -> None:
    scene, _, _, _, _ = _scene(0)
    marker = np.full(len(scene.field), -1)
    new = late_pairs(scene, marker, np.zeros(0, dtype=np.int64), np.zeros((0, 3)))
    assert len(new.field) == 0


def test_used_blobs_stay_with_their_points() -> None:
    scene, p_field, p_xyz, _, _ = _scene(0)
    marker = np.full(len(scene.field), -1)
    marker[scene.field >= 13] = 0  # taken by some point already
    new = late_pairs(scene, marker, p_field, p_xyz)
    assert set(new.field.tolist()) <= {10, 11, 12}
    assert np.all(marker[np.r_[new.own_row, new.merged_row]] < 0)
