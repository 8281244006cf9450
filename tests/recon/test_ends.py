"""Free two-camera pairs taken at a trajectory's end, gated by its prediction."""

from __future__ import annotations

import numpy as np

from kisscal.dlt.model import project
from kisscal.recon import ReconParams
from kisscal.recon.deblend import MergeScene
from kisscal.recon.ends import extend_ends

from .rig import make_rig


def _scene(dlts: np.ndarray, blobs: list[tuple[int, int, np.ndarray]]) -> MergeScene:
    """A 2D table of (field, camera, point) blobs, projected with 0.05 px of noise."""
    rng = np.random.default_rng(0)
    field = np.array([f for f, _, _ in blobs])
    camera = np.array([c for _, c, _ in blobs])
    uv = np.array([project(dlts[c], x) for _, c, x in blobs]) + rng.normal(0, 0.05, (len(blobs), 2))
    return MergeScene(field, camera, uv, field >= 0, dlts, ReconParams(), 0.2)


def _walk(n: int) -> np.ndarray:
    """A marker at 12 mm per field, gently curving."""
    t = np.arange(n, dtype=float)
    return np.column_stack([-300.0 + 12.0 * t, 0.05 * t**2, 900.0 + 0.0 * t])


def test_a_trajectory_is_continued_by_the_pair_its_prediction_gates() -> None:
    # points of fields 0-9 made (by deblending, say); fields 10-12 seen by cameras 0 and
    # 1, each field also a single-view marker in camera 1 200 mm off: one field per call
    dlts = make_rig(0, n_cameras=3)
    x = _walk(13)
    other = x + [0.0, 0.0, 200.0]
    blobs = [(f, c, x[f]) for f in range(10, 13) for c in (0, 1)]
    blobs += [(f, 1, other[f]) for f in range(10, 13)]
    scene = _scene(dlts, blobs)
    marker = np.full(len(blobs), -1)
    new = extend_ends(scene, marker, np.arange(10), x[:10])
    assert new.field.tolist() == [10]
    assert np.linalg.norm(new.xyz_mm[0] - x[10]) < 1.0
    assert {scene.camera[new.own_row[0]], scene.camera[new.merged_row[0]]} == {0, 1}


def test_two_pairs_in_one_prediction_gate_are_left_out() -> None:
    # a second marker 6 mm from the first in field 10, both seen by cameras 0 and 1:
    # either pair could continue the trajectory, so neither does
    dlts = make_rig(0, n_cameras=3)
    x = _walk(11)
    twin = x[10] + [0.0, 6.0, 0.0]
    blobs = [(10, c, p) for c in (0, 1) for p in (x[10], twin)]
    scene = _scene(dlts, blobs)
    new = extend_ends(scene, np.full(len(blobs), -1), np.arange(10), x[:10])
    assert len(new.field) == 0
