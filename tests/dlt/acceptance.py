"""Issue 8 "Done when" measurements on the synthetic KISS rig (kisscal.synth).

Linearised rod-image blobs are stood in for by the true cameras' ideal projections plus
Gaussian noise (``NOISE_PX`` per coordinate), with the other cameras' LED rings and a few
random noise blobs present and, in one camera per seed, one rod marker hidden.

Run ``python -m tests.dlt.acceptance`` from the worktree root for the table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kisscal.dlt import (
    DltParams,
    calibrate_camera,
    leave_one_rod_out,
    make_rods,
    recognise_rods,
    triangulate_dlt,
)
from kisscal.errors import KisscalError
from kisscal.synth.cameras import kiss_rig
from kisscal.synth.motion import stick_trial
from kisscal.synth.scene import rod_set

NOISE_PX = 0.05
N_NOISE_BLOBS = 4
METHODS = {
    "dlt": DltParams(),
    "mdlt": DltParams(mdlt=True),
    "refined": DltParams(refine=True),
    "mdlt+refined": DltParams(mdlt=True, refine=True),
}


@dataclass(frozen=True)
class RodImages:
    rods: tuple
    blobs: list  # per camera (M, 2)
    truth: list  # per camera (24,) blob index of each rod marker, -1 hidden
    cameras: tuple


def rod_images(seed: int, hide: bool = True, n_noise: int = N_NOISE_BLOBS) -> RodImages:
    """Blobs of each camera's rod image: markers, LED rings of facing cameras, noise.

    ``n_noise`` random noise blobs are added per image, each at least 4 px from a marker.
    """
    rng = np.random.default_rng([seed, 8008])
    cams = kiss_rig(seed)
    rods = make_rods([(r.name, r.points_mm) for r in rod_set(seed)])
    xyz = np.concatenate([r.points_mm for r in rods])
    hidden_cam = seed % len(cams) if hide else -1
    hidden = int(rng.integers(len(xyz)))
    blobs, truths = [], []
    for ic, cam in enumerate(cams):
        uv = cam.project_ideal(xyz) + rng.normal(0, NOISE_PX, (len(xyz), 2))
        others = np.array([c.centre_mm for c in cams if c.id != cam.id])
        led = cam.project_ideal(others[cam.depth_mm(others) > 0])
        led = led[cam.in_image(led, margin_px=2)]
        extra = list(led)
        w, h = cam.size_px
        while len(extra) < len(led) + n_noise:
            p = rng.uniform([0, 0], [w - 1, h - 1])
            if np.linalg.norm(uv - p, axis=1).min() > 4:
                extra.append(p)
        keep = np.setdiff1d(np.arange(len(xyz)), [hidden] if ic == hidden_cam else [])
        b = np.concatenate([uv[keep], np.reshape(extra, (-1, 2))])
        perm = rng.permutation(len(b))
        truth = np.full(len(xyz), -1)
        truth[keep] = np.argsort(perm)[: len(keep)]
        blobs.append(b[perm])
        truths.append(truth)
    return RodImages(rods, blobs, truths, cams)


def stick_observations(seed: int, cams) -> tuple[np.ndarray, np.ndarray]:
    """The stick trial's markers (not used for calibration) seen with the same noise."""
    rng = np.random.default_rng([seed, 8009])
    xyz = stick_trial(seed).xyz_mm.reshape(-1, 3)
    uv = np.stack([c.project_ideal(xyz) for c in cams])
    uv = uv + rng.normal(0, NOISE_PX, uv.shape)
    inside = np.stack([c.in_image(u) for c, u in zip(cams, uv, strict=True)])
    return xyz, np.where(inside[..., None], uv, np.nan)


def measure(seed: int, methods=METHODS) -> dict:
    """Recognition and accuracy figures of one seed, per calibration method."""
    imgs = rod_images(seed)
    out: dict = {"recognised": 0, "refused": 0, "wrong": 0, "cameras": len(imgs.cameras)}
    muv = []
    for ic, blobs in enumerate(imgs.blobs):
        try:
            m = recognise_rods(blobs, imgs.rods, camera=imgs.cameras[ic].id)
        except KisscalError:
            out["refused"] += 1
            muv.append(np.full((4, 6, 2), np.nan))
            continue
        got = m.blob_index.ravel()
        out["recognised"] += int(np.array_equal(got, imgs.truth[ic]))
        out["wrong"] += int(np.any((got >= 0) & (got != imgs.truth[ic])))
        muv.append(m.marker_uv(blobs))
    muv = np.array(muv)
    xyz = np.concatenate([r.points_mm for r in imgs.rods])
    stick_xyz, stick_uv = stick_observations(seed, imgs.cameras)
    rod_uv = muv.reshape(len(imgs.cameras), -1, 2)
    for name, params in methods.items():
        results = []
        for ic, cam in enumerate(imgs.cameras):
            seen = np.isfinite(rod_uv[ic]).all(axis=1)
            results.append(calibrate_camera(xyz[seen], rod_uv[ic][seen], params, cam.id))
        Ls = np.array([r.L for r in results])
        rec, _ = triangulate_dlt(Ls, rod_uv)
        rod_err = np.linalg.norm(rec - xyz, axis=1)
        srec, _ = triangulate_dlt(Ls, stick_uv)
        s_err = np.linalg.norm(srec - stick_xyz, axis=1)
        check = leave_one_rod_out(muv, imgs.rods, params)
        out[name] = {
            "rms_px": np.array([r.rms_px for r in results]),
            "centre_mm": np.array(
                [
                    np.linalg.norm(r.centre_mm - c.centre_mm)
                    for r, c in zip(results, imgs.cameras, strict=True)
                ]
            ),
            "rod_mean_mm": float(np.nanmean(rod_err)),
            "stick_rmse_mm": float(np.sqrt(np.nanmean(s_err**2))),
            "loo_mean_mm": check.overall_mean_mm,
            "loo_max_mm": check.overall_max_mm,
            "constraint": np.array([abs(r.constraint) for r in results]),
        }
    return out


def main(seeds=range(20)) -> None:
    rows = [measure(s) for s in seeds]
    n_cam = sum(r["cameras"] for r in rows)
    print(f"seeds {seeds.start}..{seeds.stop - 1}, noise {NOISE_PX} px per coordinate")
    print(
        f"rod recognition: {sum(r['recognised'] for r in rows)}/{n_cam} cameras fully correct, "
        f"{sum(r['refused'] for r in rows)} refused, {sum(r['wrong'] for r in rows)} with a "
        "wrong blob"
    )
    hdr = (
        "method         rms_px max  rms_px mean  centre_mm max  rods mean_mm (worst seed)  "
        "stick RMSE_mm (worst)  LOO mean_mm (max)  |Hatze| max"
    )
    print(hdr)
    for name in METHODS:
        m = [r[name] for r in rows]
        rms = np.concatenate([x["rms_px"] for x in m])
        cen = np.concatenate([x["centre_mm"] for x in m])
        rod = np.array([x["rod_mean_mm"] for x in m])
        st = np.array([x["stick_rmse_mm"] for x in m])
        loo = np.array([x["loo_mean_mm"] for x in m])
        loo_max = np.array([x["loo_max_mm"] for x in m])
        con = np.concatenate([x["constraint"] for x in m])
        print(
            f"{name:14s} {rms.max():11.4f}  {rms.mean():11.4f}  {cen.max():13.2f}  "
            f"{rod.mean():13.3f} ({rod.max():.3f})      {st.mean():10.3f} ({st.max():.3f})"
            f"    {loo.mean():8.3f} ({loo_max.max():.2f})   {con.max():9.1e}"
        )


if __name__ == "__main__":
    main()
