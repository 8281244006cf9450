"""A length partner found rigid only while a knee is held straight (kiss 3 seed 363)."""

from __future__ import annotations

import numpy as np

from kisscal.tracking import TrackingParams
from kisscal.tracking.segment_lengths import length_partners


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


def _four_marker_legs(n: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """Thigh wand, lateral knee, tibia wand and ankle of a left and a right leg (the knee
    marker on the flexion axis, rigid with the shank), as :func:`_legs`: (8, n, 3) with
    0.3 mm noise, and the left knee's flexion (n,)."""
    f = np.arange(n)
    out = []
    for side, phase in ((1.0, 0.0), (-1.0, np.pi)):
        wave = np.sin(2 * np.pi * f / 100 + phase)
        hip_a, shank = (
            np.radians(25) * wave,
            np.radians(25) * wave - np.radians(60) * np.maximum(-wave, 0),
        )
        hip = np.c_[1.2 * f, np.full(n, 90 * side), np.full(n, 900.0)]

        def along(a: np.ndarray, length: float, ahead: float) -> np.ndarray:
            c, s = np.cos(a), np.sin(a)
            return np.c_[length * s + ahead * c, np.zeros(n), ahead * s - length * c]

        knee_at = hip + along(hip_a, 420, 0)
        out += [
            hip + along(hip_a, 250, 60),
            knee_at + [0, 50 * side, 0],
            knee_at + along(shank, 160, 50),
            knee_at + along(shank, 400, 0) + [0, 40 * side, 0],
        ]
    flex = np.radians(60) * np.maximum(-np.sin(2 * np.pi * f / 100), 0)
    return np.stack(out) + np.random.default_rng(0).normal(0, 0.3, (8, n, 3)), flex


def test_a_body_fill_is_not_carried_by_a_length_held_only_in_stance():
    # modern 3 seed 353: RANK carried by RTHI (rigid over RTHI's stance fields only)
    from kisscal.tracking.gaps import fill_gaps_logged
    from tests.tracking.test_bodyfill import _tracks_of

    xyz, flex = _four_marker_legs()
    names = ("LTHI", "LKNE", "LTIB", "LANK", "RTHI", "RKNE", "RTIB", "RANK")
    # the left tibia seen only in stance: each swing is a gap for the body to fill
    out, fills = fill_gaps_logged(_tracks_of(xyz, {2: flex > 0}), TrackingParams(), labels=names)
    err = np.linalg.norm(out.positions() - xyz, axis=2)
    assert fills and all(g.track == 2 and 0 not in g.donors for g in fills)
    for g in fills:
        true = err[2, g.first_field : g.first_field + g.n_fields]
        assert np.all(true <= max(2 * g.expected_error_mm, 3.0))  # main: 101 mm, expecting 2.3


def test_the_mirror_may_cover_more_or_fewer_rows_than_the_partners_tried():
    # rows appended after the tracks (markers no track took) have no mirror entry, and a
    # mirror may name such a row where only the tracks are tried
    xyz, flex = _legs()
    dense = xyz.copy()
    dense[1, flex > 0] = np.nan
    params = TrackingParams()
    mirror = np.array([3, 4, 5, 0, 1, 2])
    want = length_partners(dense, 1, params, mirror)[0].tolist()
    assert length_partners(np.concatenate([dense, xyz[:1]]), 1, params, mirror)[0].tolist() == [
        2,
        6,
    ]
    assert length_partners(dense, 1, params, np.r_[mirror, 6])[0].tolist() == want
