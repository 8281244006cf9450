"""Table of the synthetic rigs of every preset and the pipeline figures they give.

Run from the repository root::

    python -m tests.synth.presets_table                  # seeds 1 2 3 of every preset
    python -m tests.synth.presets_table modern --seeds 4 5 --cameras 8
    python -m tests.synth.presets_table modern --seeds 1 2 4 7 --disk-only  # MB, seconds

Per preset and seed: what the seed drew (image size, bit depth, field rate, cameras, pixel
aspect), lens distortion at the image corners, marker and grid-dot diameters (px, outline,
over the whole markers of the short walk and the rods), background noise; then the
pipeline with detection parameters derived by hand from the truth
(:mod:`tests.synth.truth_params`): grid dots indexed and grid residual, rod markers
recognised and DLT residual, walk recall of markers seen by >= 3 cameras, 3D RMSE,
median reprojection RMS, stick length mean absolute error. The self-configured detection
of issue 11 is to be compared against these figures.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tests.synth.rig_check import RigFigures, check_rig

PRESETS = ("kiss", "modern", "lowcost")


def corner_distortion_px(fig: RigFigures) -> tuple[float, float]:
    """Smallest and largest lens displacement at the image corners over the cameras."""
    shifts = []
    for cam in fig.plan.rig:
        w, h = cam.size_px
        c = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], dtype=float)
        shifts.append(np.linalg.norm(cam.undistort_px(c) - c, axis=1))
    s = np.concatenate(shifts)
    return float(s.min()), float(s.max())


def _span(values: list[list[float] | None]) -> tuple[float, float]:
    v = [x for x in values if x is not None]
    return min(x[0] for x in v), max(x[1] for x in v)


def describe(fig: RigFigures) -> dict[str, str]:
    """One row of the table."""
    o = fig.plan.options
    markers = [
        t["markers"][k]["diameter_px"]["width"] for t in fig.truth for k in ("trials", "rods")
    ]
    dots = [t["grid_dots"]["diameter_px"]["width"] for t in fig.truth]
    noise = [t["background"]["trials_and_rods"]["noise_sigma_dn"] for t in fig.truth]
    aspect = fig.truth[0]["pixel_aspect"]
    cd, md, dd, nd = corner_distortion_px(fig), _span(markers), _span(dots), _span(noise)
    return {
        "preset": fig.preset,
        "seed": str(fig.seed),
        "image": f"{o.rig.size_px[0]}x{o.rig.size_px[1]}/{o.rig.bit_depth}b",
        "Hz": f"{o.rate_hz:g}",
        "cams": str(len(fig.plan.rig)),
        "aspect": f"{aspect:.2f}",
        "corner px": f"{cd[0]:.1f}-{cd[1]:.1f}",
        "marker px": f"{md[0]:.1f}-{md[1]:.1f}",
        "dot px": f"{dd[0]:.1f}-{dd[1]:.1f}",
        "noise DN": f"{nd[0]:.2f}-{nd[1]:.2f}",
        "grid dots": str(min(fig.grid_dots)),
        "grid px": f"{max(fig.grid_rms_px):.3f}",
        "rod mk": str(min(fig.rod_markers)),
        "DLT px": f"{max(fig.dlt_rms_px):.3f}",
        "recall": f"{fig.walk_recall:.3f}",
        "3D mm": f"{fig.walk_rmse_mm:.2f}",
        "reproj px": f"{fig.walk_reproj_px:.3f}",
        "stick mm": f"{fig.stick_mae_mm:.3f}",
    }


def print_table(rows: list[dict[str, str]]) -> None:
    keys = list(rows[0])
    widths = {k: max(len(k), *(len(r[k]) for r in rows)) for k in keys}
    print("  ".join(k.rjust(widths[k]) for k in keys))
    for r in rows:
        print("  ".join(r[k].rjust(widths[k]) for k in keys))


def disk_figures(preset: str, seed: int) -> tuple[float, float, float]:
    """MB, wall and CPU seconds of ``kisscal synth --preset`` at the default fields."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "s"
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(
            [
                sys.executable,
                "-m",
                "kisscal",
                "synth",
                str(out),
                "--preset",
                preset,
                "--seed",
                str(seed),
            ],
            check=True,
            capture_output=True,
        )
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
        size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file()) / 1e6
    return size, wall, cpu


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("presets", nargs="*", default=list(PRESETS))
    parser.add_argument("--seeds", nargs="+", type=int, default=[1, 2, 3])
    parser.add_argument("--cameras", type=int, default=None)
    parser.add_argument("--fields", type=int, default=12, help="walk and stick fields")
    parser.add_argument("--disk", action="store_true", help="also time default sessions")
    parser.add_argument("--disk-only", action="store_true", help="only time default sessions")
    args = parser.parse_args(argv)
    rows = []
    for preset in [] if args.disk_only else args.presets:
        for seed in args.seeds:
            fig = check_rig(preset, seed, args.fields, args.fields, n_cameras=args.cameras)
            rows.append(describe(fig))
            if fig.notes:
                print(f"{preset} seed {seed}: " + "; ".join(sorted(set(fig.notes))))
    if rows:
        print_table(rows)
    if args.disk or args.disk_only:
        print("\npreset  seed      MB  wall s  cpu s  (kisscal synth, default fields and cameras)")
        for preset in args.presets:
            for seed in args.seeds:
                size, wall, cpu = disk_figures(preset, seed)
                print(f"{preset:7s} {seed:4d} {size:7.0f} {wall:7.1f} {cpu:6.1f}")


if __name__ == "__main__":
    main()
