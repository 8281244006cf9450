"""A small KISS-like rig made here (6 cameras, 4 rods), independent of kisscal.synth."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from kisscal.dlt.camera import compose_dlt
from kisscal.dlt.model import project
from kisscal.dlt.rods import make_rods

SIZE_PX = (752, 291)
# Rod marker heights (mm), top to bottom: spacings chosen projectively distinct even when
# one marker is hidden (5-marker distinctness >= 0.77 % of the rod length).
ROD_Z_MM = {
    "R1": [1900, 1660, 1440, 680, 530, 100],
    "R2": [1900, 1640, 1210, 1000, 680, 100],
    "R3": [1900, 1660, 1050, 560, 330, 100],
    "R4": [1900, 1550, 1240, 910, 680, 100],
}
# Vertical edges of a 2.4 m (X, walkway) x 1.4 m (Y) x 2 m volume.
ROD_XY_MM = {"R1": (0, 0), "R2": (2400, 0), "R3": (2400, 1400), "R4": (0, 1400)}


def look_at(centre, target) -> np.ndarray:
    """Rotation lab -> camera of an upright camera at ``centre`` looking at ``target``."""
    z = np.asarray(target, float) - centre
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return np.array([x, np.cross(z, x), z])


@dataclass(frozen=True)
class Rig:
    L: np.ndarray  # (C, 11)
    K: np.ndarray  # (C, 3, 3)
    R: np.ndarray  # (C, 3, 3)
    centre_mm: np.ndarray  # (C, 3)
    rods: tuple


def kiss_rig(seed: int, n_cameras: int = 6, xs=(-900, 1200, 3300)) -> Rig:
    """Six cameras, three each side of the walkway (along X), looking along +/-Y.

    ``xs`` are the cameras' nominal X positions (mm); with -300 and 2700 the end cameras
    see two rods nearly in line.
    """
    rng = np.random.default_rng(seed)
    rods = make_rods([(n, [[*ROD_XY_MM[n], z] for z in ROD_Z_MM[n]]) for n in ROD_Z_MM])
    Ls, Ks, Rs, Cs = [], [], [], []
    for i in range(n_cameras):
        side = -1 if i % 2 == 0 else 1
        x = xs[(i // 2) % 3] + rng.normal(0, 100)
        y = 700 + side * (4200 + rng.normal(0, 150))
        C = np.array([x, y, 1100 + rng.normal(0, 100)])
        target = np.array([1200, 700, 1000]) + rng.normal(0, 60, 3)
        fu = 720 + rng.normal(0, 10)
        K = np.array(
            [[fu, 0, 376 + rng.normal(0, 3)], [0, 0.52 * fu, 145 + rng.normal(0, 2)], [0, 0, 1]]
        )
        R = look_at(C, target)
        Ls.append(compose_dlt(K, R, C))
        Ks.append(K)
        Rs.append(R)
        Cs.append(C)
    return Rig(np.array(Ls), np.array(Ks), np.array(Rs), np.array(Cs), rods)


def rod_xyz(rig: Rig) -> np.ndarray:
    return np.concatenate([r.points_mm for r in rig.rods])


def rod_image(
    rig: Rig,
    cam: int,
    rng: np.random.Generator,
    noise_px: float = 0.05,
    n_extra: int = 6,
    hide: int | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Blobs of a rod image (shuffled, extra strobe/noise blobs) and the truth index map.

    Returns ``(blobs (M, 2), truth (24,))`` with ``truth[j]`` the blob index of rod marker
    ``j`` (-1 when hidden). Extra blobs keep 4 px from markers, and two markers closer
    than 3 px (rods aligned in the view) are both left out: they would merge into one
    blob in a real image.
    """
    uv = project(rig.L[cam], rod_xyz(rig)) + rng.normal(0, noise_px, (24, 2))
    gap = np.linalg.norm(uv[:, None] - uv[None], axis=2) + 1e9 * np.eye(24)
    merged = np.flatnonzero(gap.min(axis=1) < 3)
    extra = []
    while len(extra) < n_extra:
        p = rng.uniform([0, 0], [SIZE_PX[0] - 1, SIZE_PX[1] - 1])
        if np.linalg.norm(uv - p, axis=1).min() > 4:
            extra.append(p)
    keep = np.setdiff1d(np.arange(24), np.r_[merged, [] if hide is None else [hide]])
    blobs = np.concatenate([uv[keep], np.reshape(extra, (-1, 2))])
    perm = rng.permutation(len(blobs))
    truth = np.full(24, -1)
    truth[keep] = np.argsort(perm)[: len(keep)]
    return blobs[perm], truth


@pytest.fixture(scope="session")
def rig() -> Rig:
    return kiss_rig(0)
