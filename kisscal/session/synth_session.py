"""Writing a synthetic session to disk in the DESIGN.md layout, with its ground truth.

The session is assembled in a temporary sibling folder and moved into place at the end,
so an interrupted run leaves nothing that looks like a finished session.
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import cv2
import numpy as np
import tomli_w

from kisscal.errors import InputError
from kisscal.io.c3d import read_c3d_points
from kisscal.io.files import staged_folder, table_to_csv, write_json, write_table
from kisscal.synth.cameras import truth_dict
from kisscal.synth.motion import STICK_LENGTH_MM, Motion
from kisscal.synth.plan import (
    SynthPlan,
    camera_glow,
    render_grid,
    render_rods,
    render_trial,
    trial_visibility,
)
from kisscal.synth.render import SpotSizes
from kisscal.synth.replay import replay_trial
from kisscal.synth.scene import SIZE_LEVELS
from kisscal.synth.truth import camera_detection_truth, session_detection_truth, size_ranges
from kisscal.synth.wand import render_axes, wand_tables

#: PNG compression level: fixed so that the same seed gives the same bytes.
_PNG_LEVEL = 3
#: PNG settings of images with sensor noise: Huffman coding alone packs noise as tightly
#: as deflate's matching does and in half the time.
_PNG_NOISY = (cv2.IMWRITE_PNG_COMPRESSION, 1, cv2.IMWRITE_PNG_STRATEGY)
_PNG_NOISY_STRATEGY = cv2.IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY


def _write_png(path: Path, image: np.ndarray, noisy: bool = False) -> None:
    options = (
        [*_PNG_NOISY, _PNG_NOISY_STRATEGY] if noisy else [cv2.IMWRITE_PNG_COMPRESSION, _PNG_LEVEL]
    )
    ok, buf = cv2.imencode(".png", image, options)
    if not ok:  # pragma: no cover - OpenCV failure
        raise OSError(f"could not encode {path}")
    path.write_bytes(buf.tobytes())


def session_config(plan: SynthPlan, name: str) -> dict:
    """The ``session.toml`` content (DESIGN.md schema) of a synthetic session."""
    config = {
        "session": {"name": name, "rate_hz": plan.options.rate_hz},
        "cameras": [{"id": c.id, "size": list(c.size_px)} for c in plan.rig],
        "grid": {"rows": 15, "cols": 20, "images": "grid/{camera}/*.png"},
        "rods": {
            "images": "rods/{camera}/*.png",
            "rod": [{"name": r.name, "points_mm": r.points_mm.tolist()} for r in plan.rods],
        },
        "markers": {
            "names": list(plan.marker_names),
            "template_mm": np.round(plan.template_mm, 1).tolist(),
            "segments": [list(s) for s in plan.segments],
        },
        "trials": [{"name": t, "images": f"trials/{t}/{{camera}}/*.png"} for t in plan.trials],
    }
    if "stick" in plan.trials:  # the report checks the stick trial against its true length
        config["report"] = {"stick_length_mm": STICK_LENGTH_MM}
    if plan.axes_mm is not None:
        return wand_tables(config, plan.axes_mm, plan.options.wand_only)
    return config


def load_walking5(path: Path, rate_hz: float = 50.0) -> Motion:
    """The real Vicon walking trial (walking5.c3d) as a :class:`Motion` inside the volume.

    Virtual points (joint centres, names ending in ``JC``) are dropped from the markers
    and used instead as the ends of thigh and shank capsules that occlude them. The
    trial is resampled to ``rate_hz``.
    """
    labels, xyz, rate = read_c3d_points(path)
    physical = [i for i, n in enumerate(labels) if not n.upper().endswith("JC")]
    joints = {n: xyz[:, i] for i, n in enumerate(labels) if n.upper().endswith("JC")}
    names = tuple(labels[i] for i in physical)
    return replay_trial(names, xyz[:, physical], rate, joints, out_rate_hz=rate_hz)


def _job(args: tuple[SynthPlan, str, str, int, Path]) -> dict:
    """Render and write one camera's images of one kind; trials return their truth columns
    (``centroids``) and their markers' true sizes (``sizes``)."""
    plan, kind, trial, ci, root = args
    cam = plan.rig[ci]
    if kind == "trial":
        return _trial_job(plan, trial, ci, root / "trials" / trial / cam.id)
    if kind == "grid":
        frames, truth = render_grid(plan, ci)
    else:
        frames, truth, leds = render_rods(plan, ci)
        write_table(root / "truth" / "leds" / f"{cam.id}.csv", leds)
    folder = root / kind / cam.id
    folder.mkdir(parents=True, exist_ok=True)
    for k, image in enumerate(frames):
        _write_png(folder / f"{k:06d}.png", image, plan.render.noise_sigma > 0)
    write_table(root / "truth" / kind / f"{cam.id}.csv", truth)
    return {}


_SIZE_KEYS = ("width_px", "height_px", "pixels")


def _trial_job(plan: SynthPlan, trial: str, ci: int, folder: Path) -> dict:
    folder.mkdir(parents=True, exist_ok=True)
    motion = plan.trials[trial]
    rows: dict[str, list] = {
        k: [] for k in ("field", "marker", "u", "v", "ui", "vi", "rx", "ry", "iso")
    }
    sizes: dict[str, list] = {f"{lv}_{k}": [] for lv in SIZE_LEVELS for k in _SIZE_KEYS}
    for f, image, t in render_trial(plan, trial, ci):
        _write_png(folder / f"{f:06d}.png", image, plan.render.noise_sigma > 0)
        idx = np.flatnonzero(t.visible)
        rows["field"].append(np.full(len(idx), f))
        rows["marker"].append(np.asarray(motion.names)[idx])
        rows["u"].append(t.uv_px[idx, 0])
        rows["v"].append(t.uv_px[idx, 1])
        rows["ui"].append(t.uv_ideal_px[idx, 0])
        rows["vi"].append(t.uv_ideal_px[idx, 1])
        rows["rx"].append(t.radii_px[idx, 0])
        rows["ry"].append(t.radii_px[idx, 1])
        rows["iso"].append(t.isolated[idx])
        for lv, s in t.sizes.items():
            for k in _SIZE_KEYS:
                sizes[f"{lv}_{k}"].append(getattr(s, k)[idx])
    cat = {k: np.concatenate(v) if v else np.zeros(0) for k, v in rows.items()}
    return {
        "centroids": {
            "field": cat["field"].astype(int),
            "camera": np.full(len(cat["field"]), plan.rig[ci].id),
            "marker": cat["marker"],
            "u_px": cat["u"],
            "v_px": cat["v"],
            "u_ideal_px": cat["ui"],
            "v_ideal_px": cat["vi"],
            "rx_px": cat["rx"],
            "ry_px": cat["ry"],
            "isolated": cat["iso"].astype(bool),
        },
        "sizes": {k: np.concatenate(v) if v else np.zeros(0) for k, v in sizes.items()},
    }


def _trial_sizes(parts: list[dict]) -> dict:
    """One camera's true marker sizes over all its trials (whole, isolated markers)."""
    cent = {k: np.concatenate([p["centroids"][k] for p in parts]) for k in ("rx_px", "ry_px")}
    iso = np.concatenate([p["centroids"]["isolated"] for p in parts])
    raw = {k: np.concatenate([p["sizes"][k] for p in parts]) for k in parts[0]["sizes"]}
    sizes = {lv: SpotSizes(*(raw[f"{lv}_{k}"] for k in _SIZE_KEYS)) for lv in SIZE_LEVELS}
    diameters = 2 * np.column_stack([cent["rx_px"], cent["ry_px"]])
    return size_ranges(diameters, sizes, iso & np.isfinite(sizes["low"].pixels))


def _truth_job(args: tuple[SynthPlan, int, dict]) -> dict:
    plan, ci, trials = args
    return camera_detection_truth(plan, ci, trials)


def _markers_truth(plan: SynthPlan, trial: str) -> dict:
    motion = plan.trials[trial]
    vis = trial_visibility(plan, trial)  # (F, M, C)
    f, m = np.meshgrid(np.arange(motion.n_fields), np.arange(len(motion.names)), indexing="ij")
    xyz = motion.xyz_mm.reshape(-1, 3)
    keep = np.all(np.isfinite(xyz), axis=1)
    cols = {
        "field": f.ravel()[keep],
        "marker": np.asarray(motion.names)[m.ravel()][keep],
        "x_mm": xyz[keep, 0],
        "y_mm": xyz[keep, 1],
        "z_mm": xyz[keep, 2],
    }
    for ci, cam in enumerate(plan.rig):
        cols[f"visible_{cam.id}"] = vis[..., ci].ravel()[keep]
    return cols


def _map(function, jobs: list, n_jobs: int) -> list:
    """``function`` over ``jobs``, in ``n_jobs`` processes when more than one."""
    if n_jobs > 1:
        with ProcessPoolExecutor(max_workers=n_jobs) as pool:
            return list(pool.map(function, jobs))
    return [function(j) for j in jobs]


def write_synthetic_session(
    out: Path, plan: SynthPlan, name: str, *, force: bool = False, n_jobs: int = 2
) -> Path:
    """Render ``plan`` and write the session folder ``out`` (images, session.toml, truth/)."""
    out = Path(out)
    with staged_folder(out, force) as root:
        (root / "session.toml").write_text(tomli_w.dumps(session_config(plan, name)))
        write_json(root / "truth" / "cameras.json", {"cameras": [truth_dict(c) for c in plan.rig]})
        jobs = [
            (plan, kind, "", ci, root) for kind in ("grid", "rods") for ci in range(len(plan.rig))
        ]
        jobs += [(plan, "trial", t, ci, root) for t in plan.trials for ci in range(len(plan.rig))]
        results = _map(_job, jobs, n_jobs)
        for trial in plan.trials:
            parts = [
                r["centroids"]
                for j, r in zip(jobs, results, strict=True)
                if j[1] == "trial" and j[2] == trial
            ]
            cols = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
            order = np.lexsort((cols["marker"], cols["camera"], cols["field"]))
            cols = {k: v[order] for k, v in cols.items()}
            tdir = root / "truth" / "trials" / trial
            write_table(tdir / "centroids.csv", cols)
            (tdir / "markers.csv").write_text(table_to_csv(_markers_truth(plan, trial)))
        per_camera = [
            (
                plan,
                ci,
                _trial_sizes(
                    [
                        r
                        for j, r in zip(jobs, results, strict=True)
                        if j[1] == "trial" and j[3] == ci
                    ]
                ),
            )
            for ci in range(len(plan.rig))
        ]
        cameras = _map(_truth_job, per_camera, n_jobs)
        write_json(root / "truth" / "detection.json", session_detection_truth(plan, cameras))
        if plan.axes_mm is not None:
            write_axes_frames(root, plan)
    return out


def write_axes_frames(root: Path, plan: SynthPlan) -> None:
    """The L-frame's images (``axes/<camera>/``) and truth (``truth/axes/<camera>.csv``)."""
    if plan.axes_mm is None:
        raise InputError("write_axes_frames: the plan has no axes object (axes_mm)")
    for ci, cam in enumerate(plan.rig):
        frames, truth = render_axes(
            plan.rig,
            ci,
            plan.axes_mm,
            plan.render,
            plan.options.seed,
            plan.options.rod_frames,
            camera_glow(plan, ci),
        )
        folder = root / "axes" / cam.id
        folder.mkdir(parents=True, exist_ok=True)
        for k, image in enumerate(frames):
            _write_png(folder / f"{k:06d}.png", image, plan.render.noise_sigma > 0)
        write_table(root / "truth" / "axes" / f"{cam.id}.csv", truth)
