"""Synthetic 3D point clouds for tracking tests (no files, no cameras).

A 15-marker walking model at 50 Hz (sagittal two-segment legs, feet, pelvis), walking
along +X through a capture volume so markers enter and leave at different fields, with
measurement noise, dropouts of a few fields and short-lived ghost points. Lab frame:
X forward, Y left, Z up, mm.
"""

from __future__ import annotations

import numpy as np

NAMES = (
    "SACR",
    "RASI",
    "LASI",
    "RTHI",
    "RKNE",
    "RTIB",
    "RANK",
    "RHEE",
    "RTOE",
    "LTHI",
    "LKNE",
    "LTIB",
    "LANK",
    "LHEE",
    "LTOE",
)
SEGMENTS = (
    ("RKNE", "RANK"),
    ("LKNE", "LANK"),
    ("RANK", "RHEE"),
    ("LANK", "LHEE"),
    ("RASI", "LASI"),
)
RATE_HZ = 50.0


def _leg(t, phase, side):
    """Marker positions of one leg relative to the pelvis centre, (n, 6, 3)."""
    w = 2 * np.pi / 1.1
    s = w * t + phase
    hip_angle = np.deg2rad(22) * np.sin(s)
    knee_flex = np.deg2rad(30) * (1 - np.cos(s + 0.6)) + np.deg2rad(5)
    shank_angle = hip_angle - knee_flex
    foot_angle = np.deg2rad(15) * np.sin(s - 0.8)
    y = side * 90.0
    hip = np.stack([np.zeros_like(t), np.full_like(t, y), np.full_like(t, -70.0)], axis=1)

    def along(angle, length):
        return np.stack([length * np.sin(angle), np.zeros_like(angle), -length * np.cos(angle)], 1)

    knee = hip + along(hip_angle, 420.0)
    ankle = knee + along(shank_angle, 410.0)
    lateral = np.array([0.0, side * 1.0, 0.0])
    c, sn = np.cos(foot_angle)[:, None], np.sin(foot_angle)[:, None]

    def foot(dx, dz):
        return ankle + np.concatenate([c * dx - sn * dz, np.zeros_like(c), sn * dx + c * dz], 1)

    return np.stack(
        [
            0.5 * (hip + knee) + 70 * lateral,  # THI
            knee + 55 * lateral,  # KNE on the knee axis
            0.5 * (knee + ankle) + 50 * lateral,  # TIB
            ankle + 40 * lateral,  # ANK on the ankle axis
            foot(-55.0, -45.0),  # HEE
            foot(150.0, -60.0),  # TOE
        ],
        axis=1,
    )


def gait_truth(n_fields: int, seed: int = 0, speed_mm_s: float = 1300.0) -> np.ndarray:
    """True positions (15, n_fields, 3) of the walking model, NAMES order."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_fields) / RATE_HZ
    phase = rng.uniform(0, 2 * np.pi)
    w = 2 * np.pi / 1.1
    pelvis = np.stack(
        [
            -1500.0 + speed_mm_s * t,
            rng.uniform(-100, 100) + 15 * np.sin(w * t),
            950.0 + 15 * np.sin(2 * w * t),
        ],
        axis=1,
    )
    pel = np.stack([[-110.0, 0.0, 40.0], [60.0, -125.0, 30.0], [60.0, 125.0, 30.0]])
    right = _leg(t, phase, -1.0)
    left = _leg(t, phase + np.pi, 1.0)
    rel = np.concatenate([np.broadcast_to(pel, (n_fields, 3, 3)), right, left], axis=1)
    return np.transpose(rel + pelvis[:, None, :], (1, 0, 2))


def template(rotation_deg: float = 0.0, offset=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Standing-pose template (15, 3), rotated about Z and moved (any frame)."""
    pel = np.array([[-110.0, 0.0, 40.0], [60.0, -125.0, 30.0], [60.0, 125.0, 30.0]])
    # Standing: hip, knee flex, foot angles zero.
    legs = []
    for side in (-1.0, 1.0):
        y = side * 90.0
        hip = np.array([0.0, y, -70.0])
        knee = hip + np.array([0, 0, -420.0])
        ankle = knee + np.array([0, 0, -410.0])
        lat = np.array([0.0, side, 0.0])
        legs.append(
            np.stack(
                [
                    0.5 * (hip + knee) + 70 * lat,
                    knee + 55 * lat,
                    0.5 * (knee + ankle) + 50 * lat,
                    ankle + 40 * lat,
                    ankle + np.array([-55.0, 0, -45.0]),
                    ankle + np.array([150.0, 0, -60.0]),
                ]
            )
        )
    pts = np.concatenate([pel, *legs]) + np.array([0, 0, 950.0])
    a = np.deg2rad(rotation_deg)
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    return pts @ rz.T + np.asarray(offset)


def observe(
    truth: np.ndarray,
    seed: int = 0,
    noise_mm: float = 1.0,
    dropout_rate: float = 0.01,
    max_dropout: int = 4,
    ghosts_per_field: float = 1.0,
    volume_x: tuple[float, float] | None = (-1200.0, 2500.0),
    visible: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Points per field from truth: noise, dropouts, ghosts, a limited capture volume.

    With ``visible`` (n_markers, n_fields) given (e.g. the rig's "seen by >= 2 cameras"),
    it replaces the volume and the random dropouts.

    Returns field (N,), xyz (N, 3), marker (N,) (-1 for ghosts) and the visibility mask
    (n_markers, n_fields).
    """
    rng = np.random.default_rng(seed + 1000)
    n_markers, n_fields, _ = truth.shape
    if visible is None:
        visible = np.ones((n_markers, n_fields), dtype=bool)
        if volume_x is not None:
            visible &= (truth[..., 0] > volume_x[0]) & (truth[..., 0] < volume_x[1])
        starts = rng.random((n_markers, n_fields)) < dropout_rate
        for m, f in zip(*np.nonzero(starts), strict=True):
            visible[m, f : f + rng.integers(1, max_dropout + 1)] = False
    visible = visible & np.isfinite(truth).all(axis=2)
    m_idx, f_idx = np.nonzero(visible)
    xyz = truth[m_idx, f_idx] + rng.normal(0, noise_mm, (m_idx.size, 3))
    fields = [f_idx]
    points = [xyz]
    markers = [m_idx]
    n_ghosts = rng.poisson(ghosts_per_field * n_fields / 2.5)
    if n_ghosts:
        born = rng.integers(0, n_fields, n_ghosts)
        life = rng.integers(1, 5, n_ghosts)
        seen_m, seen_f = np.nonzero(visible)
        pick = rng.integers(0, seen_m.size, n_ghosts)
        born = seen_f[pick]
        centre = truth[seen_m[pick], born]
        start = centre + rng.normal(0, 150, (n_ghosts, 3))
        vel = rng.normal(0, 15, (n_ghosts, 3))
        for g in range(n_ghosts):
            k = np.arange(life[g])
            f = born[g] + k
            ok = f < n_fields
            fields.append(f[ok])
            points.append(start[g] + k[ok, None] * vel[g])
            markers.append(np.full(ok.sum(), -1))
    field = np.concatenate(fields)
    order = np.argsort(field, kind="stable")
    return field[order], np.concatenate(points)[order], np.concatenate(markers)[order], visible


def rotation(axis: int, deg: float) -> np.ndarray:
    """Rotation matrix of ``deg`` degrees about coordinate axis ``axis`` (0, 1, 2)."""
    a = np.deg2rad(deg)
    c, s = np.cos(a), np.sin(a)
    i, j = [k for k in range(3) if k != axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r
