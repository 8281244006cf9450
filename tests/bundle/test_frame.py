"""The axes object: recognised among ghosts by its distances; the lab frame it fixes."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kisscal.bundle.frame import average_static, recognise_object
from kisscal.errors import KisscalError
from kisscal.synth.wand import AXES_POINTS_MM

AXES = np.asarray(AXES_POINTS_MM)


def _seen(scale: float = 1.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    R = Rotation.random(random_state=seed).as_matrix()
    t = rng.uniform(-2000, 2000, 3)
    pts = (AXES * scale) @ R.T + t
    ghosts = rng.uniform(-4000, 4000, (5, 3))  # other cameras' lights
    return np.concatenate([ghosts[:2], pts[::-1], ghosts[2:]]), R, t


def test_recognises_the_object_and_its_rigid_motion() -> None:
    for seed in range(5):
        seen, _, _ = _seen(seed=seed)
        m = recognise_object(seen, AXES)
        assert m.index.tolist() == [5, 4, 3, 2]
        lab = seen[m.index] @ m.rotation.T + m.shift_mm
        assert np.abs(lab - AXES).max() < 1e-6 and abs(m.scale - 1) < 1e-9


def test_scale_of_a_wrong_wand_is_measured() -> None:
    seen, _, _ = _seen(scale=1.1)
    assert recognise_object(seen, AXES).scale == pytest.approx(1 / 1.1)


def test_symmetric_or_missing_objects_are_refused() -> None:
    square = np.array([[0.0, 0, 0], [300, 0, 0], [300, 300, 0], [0, 300, 0]])
    with pytest.raises(KisscalError, match="symmetric"):
        recognise_object(square + 5.0, square)
    with pytest.raises(KisscalError, match="every axes marker must be seen by two cameras"):
        recognise_object(AXES[:3], AXES)


def test_static_blobs_averaged_and_flicker_dropped() -> None:
    rng = np.random.default_rng(0)
    spots = np.array([[10.0, 20.0], [200.0, 40.0]])
    frames = [spots + rng.normal(0, 0.05, spots.shape) for _ in range(4)]
    frames[0] = np.vstack([frames[0], [[80.0, 80.0]]])  # noise in one frame only
    mean = average_static(frames)
    assert len(mean) == 2 and np.abs(mean - spots).max() < 0.1
