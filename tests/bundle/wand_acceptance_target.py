"""Known-target acceptance: matches from six seeds, and held-out points against hand lists.

For each synthetic target session (:mod:`kisscal.synth.target`): the photographs'
dots, six clicked seeds per camera (0.5 px clicking error), the target route's matches
(wrong: a matched dot more than 1 px from the point's true image), then every fifth
target point held out of every camera's fit and reconstructed from all cameras, from
cameras fitted (a) to the target route's matches, (b) to a fully hand-digitised list of
the other points (each clicked with 0.5 px error) with the same lens model, (c) to the
hand list by a plain DLT (the points route, three-dimensional targets only). The held-out
points are observed as the dots the images show, the same for every calibration.
"""

from __future__ import annotations

import numpy as np

from kisscal.bundle.quality import triangulate_points
from kisscal.camera import Camera
from kisscal.dlt import calibrate_camera
from kisscal.synth.target import render_target, seed_points, target_points, target_rig
from kisscal.target.dots import find_target_dots
from kisscal.target.match import fit_camera, is_planar, match_target

CLICK_PX = 0.5


def _rmse(cameras, held, observed, xyz) -> float:
    cams, pts, uvs = [], [], []
    for c, uv in enumerate(observed):
        ok = held & np.isfinite(uv[:, 0])
        cams.append(np.full(int(ok.sum()), c))
        pts.append(np.flatnonzero(ok))
        uvs.append(uv[ok])
    est = triangulate_points(
        cameras, np.concatenate(cams), np.concatenate(pts), np.concatenate(uvs), len(xyz)
    )
    err = np.linalg.norm(est[held] - xyz[held], axis=1)
    return float(np.sqrt(np.nanmean(err**2)))


def target_case(kind: str, seed: int) -> dict:
    xyz, surfaces = target_points(kind)
    rig = target_rig(seed)
    held = np.arange(len(xyz)) % 5 == 2
    route, hand, dlt, observed = [], [], [], []
    matched = visible = wrong = 0
    for ci, cam in enumerate(rig):
        rng = np.random.default_rng([seed, ci])
        image = render_target(cam, xyz, surfaces, rng)
        uv_seed, xyz_seed = seed_points(cam, xyz, rng)
        dots = find_target_dots(image, uv_seed)
        m = match_target(xyz, uv_seed, xyz_seed, dots, cam.size_px, cam.id)
        truth = cam.project(xyz)
        ok = m.matched
        matched += int((ok & m.visible).sum())
        visible += int(m.visible.sum())
        wrong += int((np.linalg.norm(dots[m.dot[ok]] - truth[ok], axis=1) > 1.0).sum())
        d = np.linalg.norm(truth[:, None] - dots[None], axis=2)
        seen = np.where((d.min(axis=1) < 1.0)[:, None], dots[d.argmin(axis=1)], np.nan)
        observed.append(seen)
        train = ok & ~held
        route.append(fit_camera(xyz[train], dots[m.dot[train]], cam.size_px, m.camera))
        clicks = truth + rng.normal(0, CLICK_PX, truth.shape)
        start = (
            None
            if is_planar(xyz)
            else Camera.from_dlt(calibrate_camera(xyz[~held], clicks[~held]).L)
        )
        hand.append(fit_camera(xyz[~held], clicks[~held], cam.size_px, start))
        if not is_planar(xyz):
            L = calibrate_camera(xyz[~held], clicks[~held]).L
            dlt.append(Camera.from_dlt(L))
    plain = [Camera(c.K, c.R, c.t, np.zeros(5)) for c in dlt]
    return {
        "kind": kind,
        "seed": seed,
        "matched": matched,
        "visible": visible,
        "wrong": wrong,
        "route": _rmse(route, held, observed, xyz),
        "hand": _rmse(hand, held, observed, xyz),
        "dlt": _rmse(plain, held, observed, xyz) if plain else float("nan"),
    }


def target_tables(seeds) -> None:
    print(
        "\n### Known target from 6 seeds per camera (3 cameras): matches, and held-out "
        "target points (every 5th) 3D RMSE (mm)\n"
    )
    print(
        "| target | seed | matched / visible | wrong matches | target route | "
        "hand-digitised list, same lens model | hand list, plain DLT (points route) |"
    )
    print("|---|---|---|---|---|---|---|")
    for kind in ("planar", "stepped"):
        for seed in seeds:
            r = target_case(kind, seed)
            share = 100.0 * r["matched"] / max(r["visible"], 1)
            dlt = "n/a (flat)" if np.isnan(r["dlt"]) else f"{r['dlt']:.3f}"
            print(
                f"| {kind} | {seed} | {r['matched']} / {r['visible']} ({share:.1f} %) | "
                f"{r['wrong']} | {r['route']:.3f} | {r['hand']:.3f} | {dlt} |"
            )
