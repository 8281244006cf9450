"""A length partner found rigid only while a knee is held straight (kiss 3 seed 363)."""

from __future__ import annotations

import numpy as np

from kisscal.tracking import TrackingParams
from kisscal.tracking.raychain import length_partners


def _legs(n: int = 200, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Thigh, tibia and ankle markers of a left and a right leg walking (sagittal hip and
    knee angles, the knee straight in stance and bent in swing, the right leg half a
    cycle later): (6, n, 3) with 0.3 mm noise, and the left knee's flexion (n,)."""
    f = np.arange(n)
    out, flex = [], []
    for side, phase in ((1.0, 0.0), (-1.0, np.pi)):
        wave = np.sin(2 * np.pi * f / 100 + phase)
        hip_a, knee = np.radians(25) * wave, np.radians(60) * np.maximum(-wave, 0)
        hip = np.c_[1.2 * f, np.full(n, 90 * side), np.full(n, 900.0)]

        def along(a: np.ndarray, length: float, ahead: float) -> np.ndarray:
            return (
                np.c_[length * np.sin(a) + ahead * np.cos(a), np.zeros(n), -length * np.cos(a)]
                + np.c_[np.zeros(n), np.zeros(n), ahead * np.sin(a)]
            )

        knee_at = hip + along(hip_a, 420, 0)
        shank = hip_a - knee
        out += [
            hip + along(hip_a, 250, 60),  # thigh wand
            knee_at + along(shank, 160, 50),  # tibia wand
            knee_at + along(shank, 400, 0) + [0, 40 * side, 0],  # ankle
        ]
        flex.append(knee)
    xyz = np.stack(out) + np.random.default_rng(seed).normal(0, 0.3, (6, n, 3))
    return xyz, flex[0]


def test_a_pair_rigid_only_while_its_knee_is_straight_is_no_partner_beside_its_mirror():
    xyz, flex = _legs()
    params = TrackingParams()
    dense = xyz.copy()
    dense[1, flex > 0] = np.nan  # the left tibia seen only in stance (knee straight)
    # truth over the trial: the thigh wand is across the knee, the ankle on the shank
    true_sd = np.std(np.linalg.norm(xyz[[0, 2]] - xyz[1][None], axis=2), axis=1)
    assert true_sd[0] > 2 * params.rigid_fill_sd_mm and true_sd[1] < 1.0
    alone, _ = length_partners(dense, 1, params)
    assert 0 in alone.tolist()  # over stance alone the thigh looks rigid with the tibia
    mirror = np.array([3, 4, 5, 0, 1, 2])
    partners, _ = length_partners(dense, 1, params, mirror)
    assert partners.tolist() == [2]  # the right thigh-tibia pair swings meanwhile
