"""The analytic Jacobian of the adjustment against finite differences."""

from __future__ import annotations

import numpy as np

from kisscal.bundle.model import State, project, wand_jacobian, wand_points
from kisscal.camera import Camera
from kisscal.synth.cameras import kiss_rig


def _state() -> State:
    rng = np.random.default_rng(0)
    cams = []
    for c in kiss_rig(1)[:3]:
        K = c.K.copy()
        K[0, 1] = 1.5
        cams.append(Camera(K, c.R, c.t, np.array([-0.2, 0.05, 1e-3, -2e-3, 0.02])))
    d = rng.normal(size=(4, 3))
    return State.of(tuple(cams), rng.uniform(-500, 500, (4, 3)) + [0, 0, 1000], d)


def test_camera_and_wand_jacobians_match_finite_differences() -> None:
    state = _state()
    camera = np.array([0, 1, 2, 0, 1, 2, 1])
    field = np.array([0, 1, 2, 3, 0, 1, 3])
    offsets = np.array([-250.0, 60.0, 250.0, -250.0, 250.0, 60.0, -60.0])
    xyz = wand_points(state, field, offsets)
    uv, jc, jp = project(state, camera, xyz)
    jw = wand_jacobian(state, field, offsets, jp)
    n_c, n_f = len(state.R), len(state.centre_mm)
    for k in range(16):
        h = 1e-6 * max(1.0, abs(np.r_[state.intrinsics[0], 0, 0, 0, state.t[0], 0, 0, 0, 0, 0][k]))
        step = np.zeros((n_c, 16))
        step[:, k] = h
        moved = state.moved(step, np.zeros((n_f, 5)))
        num = (project(moved, camera, wand_points(moved, field, offsets), False)[0] - uv) / h
        assert np.allclose(num, jc[:, :, k], rtol=1e-4, atol=1e-4 * np.abs(jc[:, :, k]).max())
    for k in range(5):
        step = np.zeros((n_f, 5))
        step[:, k] = 1e-6
        moved = state.moved(np.zeros((n_c, 16)), step)
        num = (project(moved, camera, wand_points(moved, field, offsets), False)[0] - uv) / 1e-6
        assert np.allclose(num, jw[:, :, k], rtol=1e-4, atol=1e-3)
