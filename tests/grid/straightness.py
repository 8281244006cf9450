"""Measure the straightness ratio of issue 3 against corner distortion and centroid noise.

Run ``python -m tests.grid.straightness [--rendered]`` from the worktree root. It prints:

* a sweep over the lens distortion at the grid corners (the controlled camera of
  ``grid_synth``, lens coefficients scaled) at a given per-coordinate centroid noise,
  averaged over seeds: straightness RMS before/after, their ratio (what
  ``LinearisationQuality`` reports), the noise-free ("systematic") ratio where the fitted
  polynomial is applied to the noise-free dots, and the corrected grid residual RMS;
* with ``--rendered``: the rig cameras of ``kisscal synth`` seeds 1-3, their rendered grid
  frames through detection: the per-coordinate centroid error of one frame and of the
  4-frame average against truth, and the ratios of the real fit.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, replace

import numpy as np

from kisscal.grid import (
    apply_linearisation,
    linearise_dots,
    straightness_noise_floor_px,
    straightness_rms,
)
from tests.grid.grid_synth import BrownCamera, make_grid_view

LENS = ("k1", "k2", "k3", "p1", "p2")


@dataclass(frozen=True)
class Row:
    corner_px: float
    noise_px: float
    before_px: float
    after_px: float
    ratio: float
    ratio_min: float
    floor_ratio: float
    systematic_ratio: float
    residual_px: float


def corner_distortion_px(view) -> float:
    """Largest displacement (distorted - ideal) of the four corner dots, px."""
    corners = (view.row == view.row.max()) | (view.row == 0)
    corners &= (view.col == view.col.max()) | (view.col == 0)
    return float(np.linalg.norm(view.distorted_uv - view.ideal_uv, axis=1)[corners].max())


def scaled_camera(corner_px: float) -> BrownCamera:
    """The grid_synth camera with every lens coefficient scaled to ``corner_px`` at the corners.

    The displacement of a fixed ideal point is linear in (k1, k2, k3, p1, p2), so one
    scale factor sets it exactly.
    """
    base = BrownCamera()
    c1 = corner_distortion_px(make_grid_view(0, noise_px=0.0, camera=base))
    s = corner_px / c1
    return replace(base, **{k: getattr(base, k) * s for k in LENS})


def measure(corner_px: float, noise_px: float, seeds: range) -> Row:
    """Straightness figures averaged over ``seeds`` (ratios: mean and worst seed)."""
    cam = scaled_camera(corner_px)
    before, after, sys_ratio, resid = [], [], [], []
    for seed in seeds:
        v = make_grid_view(seed, noise_px=noise_px, camera=cam)
        fit = linearise_dots(v.dots_uv, size_px=cam.size_px)
        q = fit.linearisation.quality
        before.append(q.straightness_rms_before_px)
        after.append(q.straightness_rms_after_px)
        resid.append(q.residual_rms_after_px)
        clean = apply_linearisation(fit.linearisation, v.distorted_uv)
        sys_ratio.append(
            straightness_rms(v.distorted_uv, v.row, v.col) / straightness_rms(clean, v.row, v.col)
        )
    b, a = np.array(before), np.array(after)
    return Row(
        corner_px,
        noise_px,
        float(b.mean()),
        float(a.mean()),
        float(np.mean(b / a)),
        float(np.min(b / a)),
        float(b.mean() / straightness_noise_floor_px(noise_px, v.row, v.col)),
        float(np.mean(sys_ratio)),
        float(np.mean(resid)),
    )


def sweep(corners_px, noise_px: float, seeds: range) -> list[Row]:
    return [measure(c, noise_px, seeds) for c in corners_px]


def measure_rig(corner_px: float, noise_px: float, rig_seed: int = 1, n_noise: int = 2) -> Row:
    """As :func:`measure`, on the six ``kisscal synth`` cameras of ``rig_seed``, lens scaled.

    Each camera's lens coefficients are scaled so that its own grid view (the rig's
    tilted, rolled grid) sees ``corner_px`` at the worst corner; ``n_noise`` noise draws
    per camera.
    """
    from kisscal.synth.cameras import kiss_rig
    from kisscal.synth.scene import grid_view

    before, after, sys_ratio, resid = [], [], [], []
    row, col = np.divmod(np.arange(300), 20)
    for cam in kiss_rig(rig_seed):
        v1 = grid_view(cam, rig_seed)
        c1 = np.linalg.norm(v1.uv_px - v1.uv_ideal_px, axis=1)[[0, 19, 280, 299]].max()
        lens = cam.lens * (corner_px / c1)  # every Brown term scaled alike
        v = grid_view(replace(cam, lens=lens), rig_seed)
        for k in range(n_noise):
            rng = np.random.default_rng([rig_seed, k, int(cam.id.removeprefix("cam"))])
            dots = v.uv_px + rng.normal(0.0, noise_px, v.uv_px.shape)
            fit = linearise_dots(dots, size_px=cam.size_px)
            q = fit.linearisation.quality
            before.append(q.straightness_rms_before_px)
            after.append(q.straightness_rms_after_px)
            resid.append(q.residual_rms_after_px)
            clean = apply_linearisation(fit.linearisation, v.uv_px)
            sys_ratio.append(
                straightness_rms(v.uv_px, row, col) / straightness_rms(clean, row, col)
            )
    b, a = np.array(before), np.array(after)
    fl = straightness_noise_floor_px(noise_px, row, col)
    return Row(
        corner_px,
        noise_px,
        float(b.mean()),
        float(a.mean()),
        float(np.mean(b / a)),
        float(np.min(b / a)),
        float(b.mean() / fl),
        float(np.mean(sys_ratio)),
        float(np.mean(resid)),
    )


def format_rows(rows: list[Row]) -> list[str]:
    out = [
        "corner_px noise_px before_px after_px ratio ratio_min before/floor systematic_ratio"
        " residual_px",
    ]
    for r in rows:
        out.append(
            f"{r.corner_px:9.1f} {r.noise_px:8.3f} {r.before_px:9.3f} {r.after_px:8.4f} "
            f"{r.ratio:5.1f} {r.ratio_min:9.1f} {r.floor_ratio:12.1f} {r.systematic_ratio:16.0f} "
            f"{r.residual_px:11.4f}"
        )
    return out


def rendered(seeds=(1, 2, 3), sensor_noise: float | None = None) -> list[str]:
    """Rendered rig grid frames through detection: centroid noise and straightness ratios.

    ``sensor_noise`` (grey levels per pixel) overrides the renderer's ``noise_sigma``
    (0 in ``kisscal synth``: its frames differ only by a few speckles, so the centroid
    error is a fixed pixel-phase bias that frame averaging cannot reduce).
    """
    from scipy.spatial import cKDTree

    from kisscal.grid import dots_from_frames, linearise_frames
    from kisscal.synth.plan import SynthOptions, plan_session, render_grid

    out = [
        f"sensor noise_sigma = {sensor_noise} grey levels (None: the synth default)",
        "seed cam  corner_px err1_px err4_px  before_px after_px ratio  floor4_px residual_px",
    ]
    for seed in seeds:
        opts = SynthOptions(seed=seed, fields=10, stick_fields=10)
        if sensor_noise is not None:
            opts = replace(opts, render=replace(opts.render, noise_sigma=sensor_noise))
        plan = plan_session(opts)
        for k, cam in enumerate(plan.rig):
            frames, truth = render_grid(plan, k)
            true_uv = np.column_stack([truth["u_px"], truth["v_px"]])
            ideal = np.column_stack([truth["u_ideal_px"], truth["v_ideal_px"]])
            corner = np.linalg.norm(true_uv - ideal, axis=1)[[0, 19, 280, 299]].max()

            def err(dots, true_uv=true_uv):
                d, j = cKDTree(dots).query(true_uv)
                ok = d < 1.0
                # Per-coordinate RMS after removing the mean offset (a common shift is a
                # translation the linearisation cannot see and straightness ignores).
                e = dots[j[ok]] - true_uv[ok]
                return float(np.sqrt(np.mean((e - e.mean(axis=0)) ** 2)))

            e1 = err(dots_from_frames(frames[:1]))
            e4 = err(dots_from_frames(frames))
            q = linearise_frames(frames).linearisation.quality
            floor = straightness_noise_floor_px(e4, truth["row"], truth["col"])
            out.append(
                f"{seed:4d} {cam.id:4s} {corner:9.2f} {e1:7.4f} {e4:7.4f}  "
                f"{q.straightness_rms_before_px:9.3f} {q.straightness_rms_after_px:8.4f} "
                f"{q.straightness_rms_before_px / q.straightness_rms_after_px:5.1f}  "
                f"{floor:9.4f} {q.residual_rms_after_px:11.4f}"
            )
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--noise", type=float, nargs="+", default=[0.05, 0.01])
    ap.add_argument("--corners", type=float, nargs="+", default=[5, 6, 8, 10, 12, 16, 20, 24])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--rendered", action="store_true")
    ap.add_argument(
        "--sensor-noise",
        type=float,
        nargs="*",
        default=[],
        help="also render with this sensor noise_sigma (grey levels)",
    )
    a = ap.parse_args()
    for noise in a.noise:
        print(f"grid_synth camera (tests/grid/grid_synth.py), {a.seeds} noise seeds")
        print("\n".join(format_rows(sweep(a.corners, noise, range(a.seeds)))))
        print()
        print("kisscal synth seed-1 rig, 6 cameras x 2 noise draws, lens scaled per camera")
        print("\n".join(format_rows([measure_rig(c, noise) for c in a.corners])))
        print()
    if a.rendered:
        for sensor in [None, *a.sensor_noise]:
            print("\n".join(rendered(sensor_noise=sensor)))
            print()


if __name__ == "__main__":
    main()
