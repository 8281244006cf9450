"""Acceptance on rendered sessions: ``kisscal synth`` images through ``kisscal calibrate``.

The written files (``linearisation/<camera>.json`` and ``dlt/<camera>.json``, read back
as :class:`~kisscal.rig.Rig`) are scored against the true cameras: held-out lab points
imaged by the true cameras (raw, distorted pixels), linearised and triangulated by the
calibrated rig.
"""

from __future__ import annotations

import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from kisscal import session
from kisscal.session.calibrated import current_rig
from kisscal.synth.cameras import VOLUME_MM
from kisscal.synth.presets import synth_options
from tests.bundle.wand_scoring import centre_errors_mm, corner_error_px, rmse_mm, volume_points
from tests.session.wand_session import truth_rig


def _calibrate(root: Path, *extra: str) -> tuple[float, float, str]:
    """``kisscal calibrate`` in a subprocess: wall seconds, CPU seconds, its output."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = subprocess.run(
        [sys.executable, "-m", "kisscal", "calibrate", str(root), *extra],
        capture_output=True,
        text=True,
        check=True,
    )
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return time.perf_counter() - t0, cpu, out.stdout


def _scores(root: Path, volume=VOLUME_MM) -> dict:
    rig, truth = current_rig(root), truth_rig(root)
    inside, shell = volume_points(volume)
    lin = [c.linearise for c in rig]
    return {
        "inside": rmse_mm(truth, lin, rig.dlts, inside, raw=True),
        "shell": rmse_mm(truth, lin, rig.dlts, shell, raw=True),
        "centres": centre_errors_mm(np.array([c.centre_mm for c in rig]), truth),
        "corners": max(corner_error_px(t, c.linearise) for t, c in zip(truth, rig, strict=True)),
    }


def image_tables(seeds, fields: int) -> None:
    rows = []
    for seed in seeds:
        with tempfile.TemporaryDirectory() as tmp:
            root = Path(tmp) / "s"
            session.synthesise(root, seed=seed, fields=20, wand_fields=fields, walking5=False)
            wall, cpu, _ = _calibrate(root, "--route", "rods")
            rods = _scores(root)
            wall, cpu, _ = _calibrate(root)
            wand = _scores(root)
            doc = json.loads((root / "out" / "dlt" / "wand.json").read_text())
            check = json.loads((root / "out" / "dlt" / "check.json").read_text())
            alone = Path(tmp) / "a"
            session.synthesise(
                alone, seed=seed, fields=20, wand_fields=fields, wand_only=True, walking5=False
            )
            _calibrate(alone)
            only = _scores(alone)
            modern = Path(tmp) / "m"
            session.synthesise(
                modern,
                preset="modern",
                seed=seed,
                fields=20,
                wand_fields=fields,
                wand_only=True,
                walking5=False,
            )
            _calibrate(modern)
            volume = synth_options("modern", seed).rig.volume_mm
            only_modern = _scores(modern, volume)
            rows.append((seed, rods, wand, doc, check, only, only_modern, wall, cpu))
    print("\n### Rendered sessions (kisscal synth --wand N; kisscal calibrate), written files\n")
    print(
        "| seed | inside 3D RMSE: rods / wand on rods / wand alone (mm) | corners/edges: rods / "
        "wand on rods | LOO rods / wand (mm) | wand length mean, SD (mm) | centre error "
        "max, wand alone (mm) | corner lens error, wand alone (px) | modern, wand alone: "
        "centres max (mm), inside RMSE (mm), corner lens (px) | calibrate wall / CPU (s) "
        "| adjustment (s) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for seed, rods, wand, doc, check, only, m, wall, cpu in rows:
        loo = check["leave_one_rod_out"]
        print(
            f"| {seed} | {rods['inside']:.3f} / {wand['inside']:.3f} / {only['inside']:.3f} | "
            f"{rods['shell']:.3f} / {wand['shell']:.3f} | "
            f"{loo['rods_alone_mean_mm']:.3f} / {loo['mean_mm']:.3f} | "
            f"{doc['length_mean_mm']:.3f}, {doc['length_sd_mm']:.3f} | "
            f"{only['centres'].max():.2f} | {only['corners']:.3f} | "
            f"{m['centres'].max():.2f}, {m['inside']:.3f}, {m['corners']:.3f} | "
            f"{wall:.1f} / {cpu:.1f} | "
            f"{doc['seconds']:.1f} |"
        )
    _targets(seeds)


def _targets(seeds) -> None:
    print("\n### Rendered target sessions (kisscal synth --target; kisscal calibrate)\n")
    print("| target | seed | matched / visible per camera | held-out points mean / max (mm) |")
    print("|---|---|---|---|")
    for kind in ("planar", "stepped"):
        for seed in seeds:
            with tempfile.TemporaryDirectory() as tmp:
                root = session.synthesise_target(Path(tmp) / "t", kind, seed=seed)
                _calibrate(root)
                doc = json.loads((root / "out" / "dlt" / "target.json").read_text())
                check = json.loads((root / "out" / "dlt" / "check.json").read_text())
                per = ", ".join(f"{e['matched']}/{e['visible']}" for e in doc["cameras"].values())
                print(
                    f"| {kind} | {seed} | {per} | {check['leave_out_mean_mm']:.3f} / "
                    f"{check['leave_out_max_mm']:.3f} |"
                )
