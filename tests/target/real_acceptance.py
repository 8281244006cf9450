"""Issue 23's known-target acceptance on a real rig: OpenPTV's cavity calibration target.

Run from the repository root (needs ``../shared/data/real/openptv-cavity``; skips without)::

    python -m tests.target.real_acceptance
    python -m tests.target.real_acceptance --seeds 4 6 --work /tmp/cavity

For each seed count a session is written (the four ``cal/camN.tif`` photographs linked,
``target.csv`` from ``target_on_a_side.txt``, seeds picked from ``camN_dots.csv`` spread
over the image and over three rows of the target, :func:`tests.target.cavity.spread_seeds`)
and ``kisscal calibrate`` runs on it with default settings. Per camera it prints:

- matched: target points the route matched to a dot it found itself, and how many of
  the points OpenPTV's calibration puts on one of OpenPTV's detections
  (``camN_dots.csv``) are among them;
- the reprojection RMS (px) of the calibration kisscal wrote (DLT + linearisation) on the
  dots it matched, and on OpenPTV's detections of the same target points;
- OpenPTV's own calibration's reprojection RMS on those detections (its model, with
  refraction through the glass wall and the water: :mod:`tests.target.openptv`);
- for scale, a plain 11-parameter DLT fitted to OpenPTV's detections (the points route)
  and the same with Kolahi's lens terms (``--lens``): their RMS on the points they were
  fitted to.

A second table isolates refraction: OpenPTV's model projects the target points each
camera sees without noise, a plain DLT and kisscal's camera model
(:func:`kisscal.target.resect.choose_camera`) are fitted to those images, and their RMS is
given on the target points and over the observed volume (x, y over the target, z from
-20 to 20 mm, ``criteria.par``), where the depth-dependence of refraction shows.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from kisscal import session
from kisscal._shared import rms_px
from kisscal.dlt import DltParams, calibrate_camera
from kisscal.errors import KisscalError
from kisscal.session.calibrated import current_rig
from tests.target.cavity import SIZE_PX, cameras, shared_data, spread_seeds, target_xyz, view
from tests.target.openptv import project as openptv_project


def write_session(root: Path, data: Path, n_seeds: int) -> Path:
    """A target session on the cavity photographs with ``n_seeds`` seeds per camera."""
    if root.exists():
        shutil.rmtree(root)
    (root / "cal").mkdir(parents=True)
    xyz = target_xyz(data)
    lines = ["x_mm,y_mm,z_mm", *(f"{x:g},{y:g},{z:g}" for x, y, z in xyz)]
    (root / "target.csv").write_text("\n".join(lines) + "\n")
    for cam in cameras(data):
        (root / "cal" / f"{cam}.tif").symlink_to(data / "cal" / f"{cam}.tif")
        v = view(data, cam)
        rows = ["u_px,v_px,x_mm,y_mm,z_mm"]
        for i in spread_seeds(v, n_seeds):
            rows.append(",".join(f"{a:g}" for a in (*v.uv_px[i], *v.xyz_mm[i])))
        (root / f"{cam}_seeds.csv").write_text("\n".join(rows) + "\n")
    listed = "".join(f'[[cameras]]\nid = "{c}"\n\n' for c in cameras(data))
    (root / "session.toml").write_text(
        '[session]\nname = "openptv-cavity"\nrate_hz = 100\n\n'
        + listed
        + '[calibration]\ntarget = "target.csv"\nimages = "cal/{camera}.tif"\n'
        + 'seeds = "{camera}_seeds.csv"\n'
    )
    return root


def camera_rows(root: Path, data: Path, n_seeds: int, seconds: float) -> list[dict]:
    """The figures of every camera of a calibrated cavity session."""
    rig = {c.id: c for c in current_rig(root)}
    doc = json.loads((root / "out" / "dlt" / "target.json").read_text())["cameras"]
    out = []
    for cam in cameras(data):
        v = view(data, cam)
        written = json.loads((root / "out" / "dlt" / f"{cam}.json").read_text())
        on_ptv = rig[cam].project(v.xyz_mm) - v.uv_px
        dlt = {}
        for name, lens in (("dlt_px", False), ("dlt_lens_px", True)):
            try:
                dlt[name] = calibrate_camera(v.xyz_mm, v.uv_px, DltParams(lens=lens), cam).rms_px
            except KisscalError:  # a flat target has no depth; a near-flat view may not converge
                dlt[name] = float("nan")
        out.append(
            {
                "camera": cam,
                "seeds": n_seeds,
                "matched": doc[cam]["matched"],
                "of_reference": int(np.isin(v.ids - 1, doc[cam]["matched_points"]).sum()),
                "reference": len(v.ids),
                "model": doc[cam]["model"],
                "kisscal_own_px": float(written["rms_px"]),
                "kisscal_openptv_px": rms_px(on_ptv),
                "openptv_px": rms_px(openptv_project(v.openptv, v.xyz_mm) - v.uv_px),
                **dlt,
                "seconds": seconds,
            }
        )
    return out


def refraction_rows(data: Path) -> list[dict]:
    """How well central projections hold OpenPTV's refraction, free of detection noise."""
    from kisscal.dlt import project as dlt_project
    from kisscal.target.resect import choose_camera, model_name, resect

    x, y, z = np.meshgrid(
        np.linspace(-40, 30, 8), np.linspace(-25, 25, 6), np.linspace(-20, 20, 9), indexing="ij"
    )
    volume = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    rows = []
    for cam in cameras(data):
        v = view(data, cam)
        uv = openptv_project(v.openptv, v.xyz_mm)
        L = calibrate_camera(v.xyz_mm, uv, DltParams(), cam).L
        fit = choose_camera(v.xyz_mm, uv, SIZE_PX, resect(v.xyz_mm, uv, SIZE_PX)[0], False)
        truth = openptv_project(v.openptv, volume)
        rows.append(
            {
                "camera": cam,
                "dlt_points_px": rms_px(dlt_project(L, v.xyz_mm) - uv),
                "model": model_name(fit.terms),
                "kisscal_points_px": rms_px(fit.camera.project(v.xyz_mm) - uv),
                "dlt_volume_px": rms_px(dlt_project(L, volume) - truth),
                "kisscal_volume_px": rms_px(fit.camera.project(volume) - truth),
            }
        )
    return rows


def print_refraction(rows: list[dict]) -> None:
    print(
        "\n| camera | plain DLT on the target points (px) | kisscal model | kisscal on the "
        "target points (px) | DLT over the volume (px) | kisscal over the volume (px) |"
    )
    print("|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['camera']} | {r['dlt_points_px']:.3f} | {r['model']} | "
            f"{r['kisscal_points_px']:.3f} | {r['dlt_volume_px']:.2f} | "
            f"{r['kisscal_volume_px']:.2f} |"
        )


def _px(value: float) -> str:
    return "did not converge" if np.isnan(value) else f"{value:.3f}"


def print_table(rows: list[dict]) -> None:
    print(
        "\n| camera | seeds | matched (of OpenPTV's dots) | model chosen | kisscal RMS on its "
        "dots (px) | kisscal RMS on OpenPTV's dots (px) | OpenPTV's calibration RMS (px) | "
        "plain DLT fitted to OpenPTV's dots (px) | DLT + lens terms (px) |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['camera']} | {r['seeds']} | {r['matched']} ({r['of_reference']} of "
            f"{r['reference']}) | "
            f"{r['model']} | {r['kisscal_own_px']:.3f} | {r['kisscal_openptv_px']:.3f} | "
            f"{r['openptv_px']:.3f} | {r['dlt_px']:.3f} | {_px(r['dlt_lens_px'])} |"
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=None, help="openptv-cavity folder")
    parser.add_argument("--seeds", type=int, nargs="+", default=[4, 6])
    parser.add_argument("--work", type=Path, default=None, help="where the sessions go")
    args = parser.parse_args(argv)
    data = args.data or shared_data()
    if data is None or not (data / "cal").is_dir():
        print("skipped: ../shared/data/real/openptv-cavity is not here")
        return 0
    work = args.work or Path(tempfile.mkdtemp(prefix="kisscal-cavity-"))
    rows = []
    for n in args.seeds:
        root = write_session(work / f"seeds{n}", data, n)
        said: list[str] = []
        t0 = time.perf_counter()
        session.calibrate(root, echo=said.append)
        seconds = time.perf_counter() - t0
        print(f"\n{n} seeds per camera ({seconds:.1f} s):", *said, sep="\n  ")
        rows += camera_rows(root, data, n, seconds)
    print_table(rows)
    print("\nOpenPTV's refraction alone (noise-free images of its model):")
    print_refraction(refraction_rows(data))
    return 0


if __name__ == "__main__":
    sys.exit(main())
