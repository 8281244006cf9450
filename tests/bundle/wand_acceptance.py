"""Issue 16 "Done when" measurements: wand on rods, wand and axes alone, known targets.

Synthetic rigs with truth (:mod:`kisscal.synth`): the ``kiss`` preset (six 752 x 291
video-field cameras) and the ``modern`` one (eight square-pixel cameras in a ring around a
4 x 2 x 2 m walkway). Unless ``--images``, the cameras' blobs are the true images of
the markers plus Gaussian noise (``NOISE_PX`` per coordinate), with the facing cameras' LED
rings as stationary ghosts; for the wand on rods, grid-linearised pixels are stood in for
by the ideal (distortion-free) images. ``--images`` also runs whole sessions rendered as
images through ``kisscal synth`` and ``kisscal calibrate``.

Run ``python -m tests.bundle.wand_acceptance [--quick] [--images]`` from the worktree root.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from kisscal.bundle.adjust import ControlPoints, WandObservations
from kisscal.bundle.params import BundleParams
from kisscal.bundle.quality import (
    end_to_end_mm,
    leave_one_group_out,
    length_figures,
    wand_markers,
)
from kisscal.bundle.wand import (
    BlobTable,
    axes_frame,
    calibrate_on_control,
    calibrate_wand_alone,
)
from kisscal.camera import Camera, camera_linearisation
from kisscal.dlt import calibrate_camera, leave_one_rod_out, make_rods
from kisscal.grid import GridParams, apply_linearisation, linearise_dots
from kisscal.synth.cameras import VOLUME_MM, kiss_rig
from kisscal.synth.plan import build_rig
from kisscal.synth.presets import synth_options
from kisscal.synth.scene import grid_view, rod_set, visibility
from kisscal.synth.wand import AXES_POINTS_MM, WAND_MARKERS_MM, wand_trial
from tests.bundle.conftest import WandScene
from tests.bundle.wand_scoring import centre_errors_mm, corner_error_px, rmse_mm, volume_points

NOISE_PX = 0.05


def _grid(cam: Camera, seed: int, noise_px: float):
    """The camera's grid linearisation, fitted by the grid stage to its 300 dots."""
    view = grid_view(cam, seed)
    rng = np.random.default_rng([seed, 17])
    dots = view.uv_px + rng.normal(0, noise_px / 2, view.uv_px.shape)  # 4 frames averaged
    return linearise_dots(dots, GridParams(), cam.size_px).linearisation


def _rods(rig, lins, seed: int, noise_px: float):
    """Rod images (three frames averaged) on the grid's linearisation, the rods' DLTs."""
    rng = np.random.default_rng([seed, 31])
    rods = rod_set(seed)
    pts = np.concatenate([r.points_mm for r in rods])
    uv = [
        apply_linearisation(
            lin, cam.project(pts) + rng.normal(0, noise_px / np.sqrt(3), (len(pts), 2))
        )
        for cam, lin in zip(rig, lins, strict=True)
    ]
    control = ControlPoints(
        np.repeat(np.arange(len(rig)), len(pts)),
        np.tile(pts, (len(rig), 1)),
        np.concatenate(uv),
        np.tile(np.repeat(np.arange(len(rods)), 6), len(rig)),
    )
    starts = [Camera.from_dlt(calibrate_camera(pts, u).L) for u in uv]
    muv = np.stack([u.reshape(len(rods), 6, 2) for u in uv])
    kits = make_rods([(r.name, r.points_mm) for r in rods])
    return control, starts, leave_one_rod_out(muv, kits).overall_mean_mm


def _ideal_of(cam: Camera, lin=None):
    if lin is None:
        return cam.undistort_px
    return lambda uv: cam.undistort_px(apply_linearisation(lin, uv))


def wand_on_rods(seed: int, fields: int, noise_px: float = NOISE_PX) -> dict:
    rig = kiss_rig(seed)
    lins = [_grid(cam, seed, noise_px) for cam in rig]
    s = WandScene(rig, wand_trial(seed, fields, 50.0), WAND_MARKERS_MM)
    raw = s.blobs(ideal=False, noise_px=noise_px, seed=seed)
    table = BlobTable(raw.field, raw.camera, _linearise_rows(raw, lins), raw.n_fields)
    control, starts, loo_rods = _rods(rig, lins, seed, noise_px)
    t0, c0 = time.perf_counter(), time.process_time()
    cal = calibrate_on_control(table, starts, control, WAND_MARKERS_MM, s.sizes, s.ids, "w")
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    inside, shell = volume_points(VOLUME_MM, seed=seed)
    before = np.stack([c.dlt for c in starts])
    after = np.stack([c.dlt for c in cal.cameras])
    grid_only = [lambda uv, lin=lin: apply_linearisation(lin, uv) for lin in lins]
    wand_lin = [_ideal_of(c, lin) for c, lin in zip(cal.cameras, lins, strict=True)]
    obs = cal.observations.subset(cal.result.inlier)
    n = len(cal.fields)
    lengths = end_to_end_mm(wand_markers(cal.cameras, obs, n, 3), WAND_MARKERS_MM)
    loo = leave_one_group_out(cal, WAND_MARKERS_MM)
    return {
        "seed": seed,
        "inside rods": rmse_mm(rig, grid_only, before, inside, raw=True),
        "inside wand": rmse_mm(rig, wand_lin, after, inside, raw=True),
        "shell rods": rmse_mm(rig, grid_only, before, shell, raw=True),
        "shell wand": rmse_mm(rig, wand_lin, after, shell, raw=True),
        "loo rods": loo_rods,
        "loo wand": float(np.mean(np.concatenate(list(loo.values())))),
        "length": length_figures(lengths, 500.0),
        "floor": _length_floor(rig, s, seed, noise_px),
        "wall": wall,
        "cpu": cpu,
    }


def _linearise_rows(table: BlobTable, lins) -> np.ndarray:
    uv = np.empty_like(table.uv_px)
    for c, lin in enumerate(lins):
        rows = table.camera == c
        uv[rows] = apply_linearisation(lin, table.uv_px[rows])
    return uv


def _length_floor(rig, s: WandScene, seed: int, noise_px: float) -> dict:
    """The wand length SD the noise alone makes: noisy ideal images, the true cameras."""
    rng = np.random.default_rng([seed, 71])
    rows = []
    for c, cam in enumerate(rig):
        f, m = np.nonzero(visibility(cam, s.motion))
        uv = cam.project_ideal(s.motion.xyz_mm[f, m]) + rng.normal(0, noise_px, (len(f), 2))
        rows.append((f, np.full(len(f), c), m, uv))
    obs = WandObservations(*(np.concatenate([r[i] for r in rows]) for i in range(4)))
    true_cams = tuple(Camera(c.K, c.R, c.t, np.zeros(5)) for c in rig)
    xyz = wand_markers(true_cams, obs, s.motion.n_fields, 3)
    return length_figures(end_to_end_mm(xyz, WAND_MARKERS_MM), 500.0)


def _axes_blobs(rig, noise_px: float, seed: int) -> list:
    rng = np.random.default_rng([seed, 53])
    axes = np.asarray(AXES_POINTS_MM)
    out = []
    for cam in rig:
        others = np.array([c.centre_mm for c in rig if c.id != cam.id])
        led = cam.project(others[cam.depth_mm(others) > 0])
        uv = cam.project(axes) + rng.normal(0, noise_px, (len(axes), 2))
        out.append(np.concatenate([uv, led[cam.in_image(led, 3.0)]]))
    return out


def wand_alone(rig, volume, seed: int, fields: int, noise_px: float = NOISE_PX) -> dict:
    s = WandScene(rig, wand_trial(seed, fields, 50.0, WAND_MARKERS_MM, volume), WAND_MARKERS_MM)
    table = s.blobs(ideal=False, noise_px=noise_px, seed=seed)
    t0 = time.perf_counter()
    cal = calibrate_wand_alone(table, WAND_MARKERS_MM, s.sizes, s.ids, "w", BundleParams())
    frame = axes_frame(
        cal.cameras,
        s.sizes,
        s.ids,
        _axes_blobs(rig, noise_px / 2, seed),
        np.asarray(AXES_POINTS_MM),
        0.03,
    )
    wall = time.perf_counter() - t0
    cams = frame.cameras(cal.cameras)
    inside, _ = volume_points(volume, seed=seed)
    dlts = np.stack([c.dlt for c in cams])
    brown = [corner_error_px(t, _ideal_of(c)) for t, c in zip(rig, cams, strict=True)]
    polys = []
    inl = cal.observations.subset(cal.result.inlier)
    for k, (t, c) in enumerate(zip(rig, cams, strict=True)):
        data = inl.uv_px[inl.camera == k]
        lin = camera_linearisation(c, t.size_px, data_px=data, minimax=True)[0]
        polys.append(corner_error_px(t, lambda uv, lin=lin: apply_linearisation(lin, uv)))
    return {
        "seed": seed,
        "centres": centre_errors_mm(np.array([c.centre_mm for c in cams]), rig),
        "inside": rmse_mm(rig, [_ideal_of(c) for c in cams], dlts, inside, raw=True),
        "shape": rmse_mm(rig, [_ideal_of(c) for c in cams], dlts, inside, True, shape_only=True),
        "corner brown": max(brown),
        "corner poly4": max(polys),
        "axes rms": frame.match.rms_mm,
        "wall": wall,
    }


def _print(title: str, headers: list[str], rows: list[list[str]]) -> None:
    print(f"\n### {title}\n")
    print("| " + " | ".join(headers) + " |")
    print("|" + "---|" * len(headers))
    for r in rows:
        print("| " + " | ".join(r) + " |")


def wand_on_rods_tables(seeds, fields: int) -> None:
    rows, lengths = [], []
    for seed in seeds:
        for noise, label in (
            (NOISE_PX, "0.05 per coordinate"),
            (NOISE_PX / np.sqrt(2), "0.05 RMS"),
        ):
            r = wand_on_rods(seed, fields, noise)
            L, F = r["length"], r["floor"]
            lengths.append(
                [
                    str(seed),
                    label,
                    f"{L['length_mean_mm']:.3f}",
                    f"{L['length_sd_mm']:.3f}",
                    f"{L['length_rms_error_mm']:.3f}",
                    f"{F['length_sd_mm']:.3f}",
                    str(L["length_fields"]),
                ]
            )
            if noise != NOISE_PX:
                continue
            rows.append(
                [str(seed)]
                + [
                    f"{r[k]:.3f}"
                    for k in ("inside rods", "inside wand", "shell rods", "shell wand")
                ]
                + [
                    f"{r['loo rods']:.3f}",
                    f"{r['loo wand']:.3f}",
                    f"{r['wall']:.1f} / {r['cpu']:.1f}",
                ]
            )
    _print(
        f"Wand on rods, KISS rig, {fields} wand fields x 6 cameras, {NOISE_PX} px noise per "
        "coordinate, the grid stage's linearisation: held-out 3D RMSE (mm), leave-one-rod-out "
        "mean (mm)",
        [
            "seed",
            "inside: rods",
            "inside: wand",
            "corners/edges: rods",
            "corners/edges: wand",
            "LOO rods",
            "LOO wand+rods",
            "adjust s wall / CPU",
        ],
        rows,
    )
    _print(
        "Wand length over the trial (floor: noisy ideal images triangulated by the true cameras)",
        [
            "seed",
            "centroid noise (px)",
            "mean (mm)",
            "SD (mm)",
            "RMS error (mm)",
            "SD with true cameras (mm)",
            "fields",
        ],
        lengths,
    )


def wand_alone_tables(seeds, fields: int) -> None:
    rows = []
    for preset in ("kiss", "modern"):
        for seed in seeds:
            options = synth_options(preset, seed)
            r = wand_alone(build_rig(options), options.rig.volume_mm, seed, fields)
            rows.append(
                [
                    preset,
                    str(seed),
                    f"{r['centres'].max():.2f}",
                    f"{r['inside']:.3f}",
                    f"{r['shape']:.3f}",
                    f"{r['corner brown']:.3f}",
                    f"{r['corner poly4']:.3f}",
                    f"{r['axes rms']:.2f}",
                    f"{r['wall']:.1f}",
                ]
            )
    _print(
        f"Wand and axes alone ({fields} fields, {NOISE_PX} px noise, raw distorted images, "
        "LED ghosts)",
        [
            "rig",
            "seed",
            "centre error max (mm)",
            "inside 3D RMSE (mm)",
            "inside, after the best similarity (mm)",
            "corner lens error, Brown (px)",
            "corner lens error, written poly4 (px)",
            "axes fit RMS (mm)",
            "s",
        ],
        rows,
    )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="one seed, 300 fields")
    ap.add_argument("--images", action="store_true", help="also rendered sessions")
    args = ap.parse_args()
    seeds = (1,) if args.quick else (1, 2, 3)
    fields = 300 if args.quick else 600
    wand_on_rods_tables(seeds, fields)
    wand_alone_tables(seeds, fields)
    from tests.bundle.wand_acceptance_target import target_tables

    target_tables(seeds)
    if args.images:
        from tests.bundle.wand_acceptance_images import image_tables

        image_tables(seeds[:1], fields)


if __name__ == "__main__":
    main()
