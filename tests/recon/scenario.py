"""Acceptance scenario: ideal projections + noise, stationary LEDs, noise blobs, merged blobs.

Works from DLT parameters alone, so the same code serves the tests' own rig and the
synthetic rig of ``kisscal.synth`` (``cam.dlt`` maps lab mm to ideal pixels, which is what
``cam.project_ideal`` returns).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import project
from kisscal.recon.epipolar import camera_centre_mm
from kisscal.recon.reconstruct import Points3D


@dataclass(frozen=True)
class Table2D:
    """Long-format 2D table with its truth (marker index, -1 for ghost blobs)."""

    field: NDArray[np.int64]
    camera: NDArray[np.int64]
    uv: NDArray[np.float64]
    truth: NDArray[np.int64]
    n_merged: int
    n_led: int
    n_noise: int


def observe(
    dlts: NDArray[np.float64],
    size_px: tuple[int, int],
    xyz: NDArray[np.float64],
    visible: NDArray[np.bool_],
    seed: int,
    noise_px: float = 0.05,
    noise_blobs: int = 2,
    leds: bool = True,
    merge_px: float = 3.0,
    merge: str = "first",
) -> Table2D:
    """Blobs of every camera and field of a trial.

    ``visible`` (n_fields, n_markers, n_cameras) says which camera sees which marker.
    Markers whose images lie within ``merge_px`` of each other give one blob: with
    ``merge="first"`` at the first marker's image (the other's observation is dropped);
    with ``merge="centroid"`` at the centroid of the union, the markers' images weighted
    by their area (``1 / depth^2``, equal spheres), as a detector's intensity centroid
    puts it (the tracking tests were tuned on the first; on the second, kiss 3 cameras
    seed 9 names 7 samples wrongly with main's reconstruction). Each camera also sees the
    LEDs of the other cameras in front of it (stationary, 0.1 px jitter) and
    ``noise_blobs`` random blobs per field.
    """
    rng = np.random.default_rng([seed, 77])
    n_fields, n_markers, _ = xyz.shape
    w, h = size_px
    parts: list[tuple[NDArray, NDArray, NDArray, NDArray]] = []
    n_merged = n_led = n_noise = 0
    safe = np.where(np.isfinite(xyz), xyz, 0.0)
    for c, L in enumerate(dlts):
        uv = project(L, safe)
        vis = visible[..., c] & np.all(np.isfinite(xyz), axis=-1)
        # one blob for markers whose images overlap: drop the later marker of each pair
        d = np.linalg.norm(uv[:, :, None] - uv[:, None, :], axis=-1)
        close = (d < merge_px) & vis[:, :, None] & vis[:, None, :]
        close &= np.triu(np.ones((n_markers, n_markers), dtype=bool), k=1)[None]
        merged = close.any(axis=1)
        n_merged += int(merged.sum())
        if merge == "centroid":
            uv = _merged_centroids(uv, safe @ L[8:11] + 1.0, close, merged, vis)
        vis = vis & ~merged
        f, m = np.nonzero(vis)
        parts.append((f, np.full(len(f), c), uv[f, m] + rng.normal(0, noise_px, (len(f), 2)), m))
        if leds:
            centres = np.array([camera_centre_mm(dlts[k]) for k in range(len(dlts)) if k != c])
            front = centres @ L[8:11] + 1.0 > 0
            led_uv = project(L, centres[front])
            inside = (led_uv[:, 0] > 2) & (led_uv[:, 0] < w - 3)
            inside &= (led_uv[:, 1] > 2) & (led_uv[:, 1] < h - 3)
            for p in led_uv[inside]:
                parts.append(
                    (
                        np.arange(n_fields),
                        np.full(n_fields, c),
                        p + rng.normal(0, 0.1, (n_fields, 2)),
                        np.full(n_fields, -1),
                    )
                )
                n_led += n_fields
        for _ in range(noise_blobs):
            parts.append(
                (
                    np.arange(n_fields),
                    np.full(n_fields, c),
                    rng.random((n_fields, 2)) * [w - 1, h - 1],
                    np.full(n_fields, -1),
                )
            )
            n_noise += n_fields
    field, camera, uv, truth = (np.concatenate(x) for x in zip(*parts, strict=True))
    perm = rng.permutation(len(field))
    return Table2D(
        field[perm].astype(np.int64),
        camera[perm].astype(np.int64),
        uv[perm],
        truth[perm].astype(np.int64),
        n_merged,
        n_led,
        n_noise,
    )


def _merged_centroids(
    uv: NDArray[np.float64],
    depth: NDArray[np.float64],
    close: NDArray[np.bool_],
    merged: NDArray[np.bool_],
    vis: NDArray[np.bool_],
) -> NDArray[np.float64]:
    """Images (n_fields, n_markers, 2) with each kept marker's image moved to the
    area-weighted centroid of itself and the markers merged into it (``close[f, k, m]``:
    m, a later marker, merges into k; chains followed to the first marker)."""
    n_fields, n_markers = uv.shape[:2]
    owner = np.where(merged, close.argmax(axis=1), np.arange(n_markers)[None])
    fi = np.arange(n_fields)[:, None]
    for _ in range(n_markers):
        nxt = owner[fi, owner]
        if np.array_equal(nxt, owner):
            break
        owner = nxt
    w = np.where(vis, 1.0 / np.maximum(depth, 1e-9) ** 2, 0.0)
    total = np.zeros((n_fields, n_markers))
    acc = np.zeros((n_fields, n_markers, 2))
    f = np.broadcast_to(fi, owner.shape)
    np.add.at(total, (f, owner), w)
    np.add.at(acc, (f, owner), w[..., None] * uv)
    out = uv.copy()
    keep = vis & ~merged & (total > 0)
    out[keep] = acc[keep] / total[keep][:, None]
    return out


@dataclass(frozen=True)
class Score:
    """Reconstruction against truth (per field, nearest true marker within ``radius_mm``)."""

    n_seen3: int
    n_found: int
    n_points: int
    n_ghosts: int
    rmse_mm: float

    @property
    def recall(self) -> float:
        return self.n_found / max(self.n_seen3, 1)

    @property
    def ghost_fraction(self) -> float:
        return self.n_ghosts / max(self.n_points, 1)


def score(points: Points3D, xyz: NDArray, visible: NDArray, radius_mm: float = 10.0) -> Score:
    """Recall of markers seen by >= 3 cameras, ghost fraction and 3D RMSE."""
    seen3 = visible.sum(axis=2) >= 3
    found = ghosts = 0
    sq: list[NDArray] = []
    order = np.argsort(points.field, kind="stable")
    bounds = np.searchsorted(points.field[order], np.arange(len(xyz) + 1))
    for f in range(len(xyz)):
        P = points.xyz_mm[order[bounds[f] : bounds[f + 1]]]
        T = xyz[f]
        ok = np.all(np.isfinite(T), axis=1)
        if len(P) == 0:
            continue
        d = np.linalg.norm(P[:, None] - T[None], axis=2)
        d[:, ~ok] = np.inf
        near = d.min(axis=1)
        ghosts += int((near > radius_mm).sum())
        sq.append(near[near <= radius_mm] ** 2)
        found += int(((d.min(axis=0) <= radius_mm) & seen3[f]).sum())
    rmse = float(np.sqrt(np.mean(np.concatenate(sq)))) if sq else float("nan")
    return Score(int(seen3.sum()), found, len(points), ghosts, rmse)
