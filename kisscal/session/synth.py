"""Synthetic sessions on disk: write one (``kisscal synth``) and score its outputs.

The file side of :mod:`kisscal.synth` (which stays pure: rigs, rendering, scoring):
:func:`synthesise` plans a rig with :mod:`kisscal.synth.plan` and writes it through
:mod:`kisscal.session.synth_session`; :func:`evaluate` compares a processed session's ``out/``
with its ``truth/``.
"""

from __future__ import annotations

import dataclasses
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from kisscal.errors import InputError
from kisscal.io.config import load_session
from kisscal.io.files import read_table
from kisscal.io.store import SessionStore
from kisscal.session.progress import quiet
from kisscal.session.synth_session import load_walking5, write_synthetic_session
from kisscal.session.synth_target import write_target_session
from kisscal.synth.evaluate import (
    score_trajectories,
    stick_length_error,
    thrown_gravity,
)
from kisscal.synth.motion import G_MM_S2
from kisscal.synth.plan import plan_session
from kisscal.synth.presets import synth_options


def default_walking5_path() -> Path | None:
    """The real walking trial shipped with kisscal (``kisscal/data/walking5.c3d``).

    ``KISSCAL_WALKING5`` names another copy; ``None`` when neither is a file.
    """
    env = os.environ.get("KISSCAL_WALKING5")
    candidates = [Path(env)] if env else []
    candidates.append(Path(__file__).resolve().parents[1] / "data" / "walking5.c3d")
    return next((p for p in candidates if p.is_file()), None)


def synthesise(
    out: Path,
    *,
    preset: str = "kiss",
    seed: int = 1,
    fields: int | None = None,
    n_cameras: int | None = None,
    n_markers: int = 15,
    blur_px: float | None = None,
    walking5: bool = True,
    force: bool = False,
    n_jobs: int | None = None,
    echo: Callable[[str], object] | None = None,
    wand_fields: int = 0,
    wand_only: bool = False,
    replay_in_view: bool = False,
    trials: tuple[str, ...] | None = None,
) -> Path:
    """Write a synthetic session (images, ``session.toml``, ``truth/``) to ``out``.

    ``preset`` is the kind of lab (:data:`kisscal.synth.presets.PRESETS`: ``kiss``,
    ``modern``, ``lowcost``); ``fields`` and ``n_cameras`` default to the preset's. The
    same arguments give byte-identical files. With ``walking5`` the real Vicon trial is
    replayed through the synthetic cameras as trial ``walk5`` when it can be found.
    ``wand_fields`` adds a wand trial ``wand01`` of that many fields and an L-frame
    (``[wand]``, ``[axes]``); ``wand_only`` leaves ``[grid]`` and ``[rods]`` out.
    ``replay_in_view`` cuts ``walk5`` to the fields the rig sees whole
    (:class:`~kisscal.synth.plan.SynthOptions`). ``trials`` writes only those trials
    (``walk01``, ``stick``, ``throw``, ``walk5``, ``wand01``), each as in the whole session.
    """
    echo = echo or quiet
    if n_markers not in (13, 15):
        raise InputError(f"--markers must be 13 or 15, got {n_markers}")
    if fields is not None and fields < 10:
        raise InputError(f"--fields must be at least 10, got {fields}")
    if wand_only and not wand_fields:
        raise InputError("--wand-only needs --wand FIELDS (the wand trial to calibrate from)")
    options = synth_options(
        preset, seed, fields=fields, n_cameras=n_cameras, n_markers=n_markers, blur_px=blur_px
    )
    options = dataclasses.replace(
        options,
        wand_fields=wand_fields,
        wand_only=wand_only,
        replay_in_view=replay_in_view,
        trials=trials,
    )
    replay = None
    if walking5:
        path = default_walking5_path()
        if path is None:
            echo("walking5.c3d not found: the real-trial replay (walk5) is skipped")
        else:
            replay = load_walking5(path, options.rate_hz)
    plan = plan_session(options, replay)
    if plan.rod_conflicts:
        echo(
            f"warning: {plan.rod_conflicts} rod-marker images touch an LED ring or another "
            f"rod in some camera (no placement of the rods is clear for {len(plan.rig)} "
            "cameras around this volume): expect fewer than 24 rod markers there"
        )
    t0 = time.perf_counter()
    write_synthetic_session(
        Path(out), plan, f"synth-seed{seed}", force=force, n_jobs=n_jobs or os.cpu_count() or 1
    )
    w, h = plan.options.rig.size_px
    echo(
        f"wrote {out}: {preset} rig, {len(plan.rig)} cameras of {w} x {h} px at "
        f"{options.rate_hz:g} Hz, grid and rod frames, trials "
        f"{', '.join(f'{t} ({m.n_fields} fields)' for t, m in plan.trials.items())}, "
        f"truth/ ({time.perf_counter() - t0:.1f} s)"
    )
    return Path(out)


def synthesise_target(
    out: Path,
    kind: str,
    *,
    seed: int = 1,
    n_cameras: int = 3,
    force: bool = False,
    echo: Callable[[str], object] | None = None,
) -> Path:
    """Write a synthetic known-target session (``kisscal synth --target planar|stepped``):
    photographs of a dot plate, ``target.csv``, six clicked seeds per camera, ``truth/``."""
    if kind not in ("planar", "stepped"):
        raise InputError(f"--target must be planar or stepped, got {kind!r}")
    if not 2 <= n_cameras <= 4:
        raise InputError(f"a target session has 2 to 4 cameras, got {n_cameras}")
    t0 = time.perf_counter()
    write_target_session(Path(out), kind, seed, n_cameras, force=force)  # type: ignore[arg-type]
    (echo or quiet)(
        f"wrote {out}: {n_cameras} cameras photographing a {kind} dot plate, "
        f"target.csv, seeds, truth/ ({time.perf_counter() - t0:.1f} s)"
    )
    return Path(out)


def evaluate(root: Path) -> dict[str, Any]:
    """Score a processed synthetic session against its ``truth/`` (no truth: empty dict).

    Gait trials: trajectories vs true markers (labels, switches, RMSE, coverage); the
    stick trial: length error (Shafiq et al. 2001, section 5.1); the thrown marker: g
    from a parabola fit.
    """
    root = Path(root)
    config = load_session(root)
    result: dict[str, Any] = {}
    for trial in config.trials:
        traj_path = SessionStore(root).trial(trial.name).trajectories()
        truth_path = root / "truth" / "trials" / trial.name / "markers.csv"
        if traj_path.is_file() and truth_path.is_file():
            result[trial.name] = _score_trial(
                trial.name, traj_path, truth_path, config.camera_ids, config.rate_hz
            )
    return result


def _score_trial(
    name: str, traj_path: Path, truth_path: Path, cameras: tuple[str, ...], rate_hz: float
) -> dict[str, Any]:
    tr = read_table(traj_path)
    truth = read_table(truth_path)
    field_t = tr["field"].astype(int)
    xyz = np.column_stack([tr["x_mm"], tr["y_mm"], tr["z_mm"]])
    vis = np.column_stack([truth[f"visible_{c}"] for c in cameras])
    score = score_trajectories(
        field_t,
        tr["label"],
        xyz,
        tr["status"],
        truth["field"].astype(int),
        truth["marker"],
        np.column_stack([truth["x_mm"], truth["y_mm"], truth["z_mm"]]),
        vis.sum(axis=1) >= 3,
    )
    entry: dict[str, Any] = dataclasses.asdict(score)
    if name == "stick":
        mae, sd, n = stick_length_error(field_t, tr["label"], xyz, tr["status"])
        entry["stick_length"] = {"mean_abs_error_mm": mae, "sd_mm": sd, "samples": n}
    if name == "throw":
        measured = tr["status"] == "measured"
        g = thrown_gravity(field_t[measured], xyz[measured], rate_hz)
        entry["gravity"] = {"g_m_s2": g, "relative_error": abs(g * 1000.0 - G_MM_S2) / G_MM_S2}
    return entry
