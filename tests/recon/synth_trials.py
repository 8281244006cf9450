"""Acceptance measurements on the synthetic KISS-like rig (``kisscal.synth``).

Run ``python -m tests.recon.synth_trials`` from the repository root for the table of the
issue's "Done when" numbers (several seeds, both strategies).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.recon import Points3D, ReconParams, reconstruct_trial

from .scenario import Score, observe, score

STICK_LENGTH_MM = 502.5
G_M_S2 = 9.806


@dataclass(frozen=True)
class Trial:
    """A synthetic trial seen by the rig: truth, visibility and the 2D table."""

    dlts: NDArray[np.float64]
    xyz: NDArray[np.float64]
    visible: NDArray[np.bool_]
    field: NDArray[np.int64]
    camera: NDArray[np.int64]
    uv: NDArray[np.float64]
    truth: NDArray[np.int64]
    rate_hz: float


def make_trial(kind: str, seed: int, n_fields: int = 200, **observe_kw: object) -> Trial:
    """``kind`` is ``walk``, ``stick`` or ``throw``; the rig and the motion follow ``seed``."""
    from kisscal.synth.cameras import kiss_rig
    from kisscal.synth.motion import stick_trial, throw_trial, walking_trial
    from kisscal.synth.scene import visibility

    rig = kiss_rig(seed)
    if kind == "walk":
        motion = walking_trial(seed, n_fields, n_markers=15)
    elif kind == "stick":
        motion = stick_trial(seed, n_fields)
    else:
        motion = throw_trial(seed)
    visible = np.stack([visibility(cam, motion) for cam in rig], axis=-1)
    dlts = np.array([cam.dlt for cam in rig])
    tab = observe(dlts, rig[0].size_px, motion.xyz_mm, visible, seed, **observe_kw)
    return Trial(
        dlts, motion.xyz_mm, visible, tab.field, tab.camera, tab.uv, tab.truth, motion.rate_hz
    )


def reconstruct(trial: Trial, params: ReconParams) -> Points3D:
    return reconstruct_trial(trial.field, trial.camera, trial.uv, trial.dlts, params)


def nearest_track(points: Points3D, xyz: NDArray[np.float64], radius_mm: float = 10.0) -> NDArray:
    """Per field and true marker, the reconstructed point nearest to it (NaN if none near)."""
    out = np.full(xyz.shape, np.nan)
    for f in range(len(xyz)):
        P = points.xyz_mm[points.field == f]
        if len(P) == 0:
            continue
        d = np.linalg.norm(P[:, None] - xyz[f][None], axis=2)
        k = d.argmin(axis=0)
        near = d[k, np.arange(len(k))] <= radius_mm
        out[f, near] = P[k[near]]
    return out


def stick_errors_mm(points: Points3D, trial: Trial) -> NDArray[np.float64]:
    """Signed stick-length errors (mm) of the fields where both markers were reconstructed."""
    track = nearest_track(points, trial.xyz)
    length = np.linalg.norm(track[:, 0] - track[:, 1], axis=1)
    return length[np.isfinite(length)] - STICK_LENGTH_MM


def thrown_g_m_s2(points: Points3D, trial: Trial) -> float:
    """Vertical acceleration (m/s^2, positive down) of a parabola fitted to the ball's Z."""
    track = nearest_track(points, trial.xyz)[:, 0]
    ok = np.isfinite(track[:, 2])
    t = np.arange(len(track))[ok] / trial.rate_hz
    c2 = np.polyfit(t, track[ok, 2], 2)[0]
    return float(-2.0 * c2 / 1000.0)


def main(seeds: tuple[int, ...] = (1, 2, 3)) -> list[str]:
    lines = ["strategy seed  recall%  ghost%  rmse_mm  stick|e|  stickSD  g_m_s2  g_err%  fields/s"]
    for strategy in ("triple", "central"):
        params = ReconParams(strategy=strategy)
        for seed in seeds:
            walk = make_trial("walk", seed)
            t0 = time.perf_counter()
            pts = reconstruct(walk, params)
            rate = len(walk.xyz) / (time.perf_counter() - t0)
            s: Score = score(pts, walk.xyz, walk.visible)
            stick = make_trial("stick", seed)
            e = stick_errors_mm(reconstruct(stick, params), stick)
            throw = make_trial("throw", seed)
            g = thrown_g_m_s2(reconstruct(throw, params), throw)
            lines.append(
                f"{strategy:8s} {seed:4d} {100 * s.recall:8.3f} {100 * s.ghost_fraction:7.3f}"
                f" {s.rmse_mm:8.3f} {np.mean(np.abs(e)):9.3f} {np.std(e):8.3f}"
                f" {g:7.3f} {100 * (g - G_M_S2) / G_M_S2:7.3f} {rate:9.0f}"
            )
    return lines


if __name__ == "__main__":
    seeds = tuple(int(a) for a in sys.argv[1:]) or (1, 2, 3)
    print("\n".join(main(seeds)))
