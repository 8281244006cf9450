"""Where the small session's processor time goes: ``kisscal run`` of the default
synthetic KISS session in this one process (one worker, figures drawn here), each part
timed in processor time and given as a multiple of decoding the session's images,
timed in the same run (issue 28's bar is the whole run within 2x the decode).

Parts are timed by wrapping the functions the session calls (detection of a chunk of frames,
reading one image, the detection set-up, the grid fit, the DLT, the exports, the
reconstruction, the tracking, the gait, the figures, the report); a stage's line holds
the parts inside it, and "other" is what no listed part covers. One process, so the
processor time is the sum of what the run's processes would spend (without their
start-up); it does not move with the load as wall time does. Session as in
:mod:`benchmarks.bench_small` (its cache folder).

Recorded (2026-11-28, 4044 images, 2 cores shared with other work at a load of about
20; the decode reference itself moved 2.75-3.35 s between runs): per-frame detection
(commit 647317e) whole run 50.65 s = 15.11x decode, detection 13.27 s = 3.96x (26 % of
the run); frames stacked by chunk (:func:`kisscal.detect.pipeline.detect_frames`) whole
run 42.78 s = 15.56x decode, detection 9.11 s = 3.31x (21 %). Within one run
:mod:`benchmarks.bench_small_detect` compares the two detection paths directly.

Every detection step stacked (cores, splits, moments too: :mod:`kisscal.detect.stack`)
and the figures' palette PNG made from Agg's pixels (2026-11-29, load about 28; the
decode reference 4.19 s before, 3.24 s after): commit a5f31b7 whole run 47.83 s
(11.42x decode), detection 10.42 s (2.49x, 21.8 %), figures 8.33 s; commit dfdb291
whole run 41.83 s (12.91x decode), detection 5.17 s (1.59x, 12.4 %), figures 7.94 s.
The other parts (tracking 4.99 s, exports 4.77 s, survey 4.49 s, DLT 4.11 s, image
reading 2.91 s, imports 2.45 s) did not change; the session's outputs are byte-identical
(every JSON, CSV, TOML and cached blob file; summary.json's timings aside).

This benchmark runs with one worker and no background process: the cost of the run's
processes (forking a pool, its workers' start and exit) is not in it. On 2026-11-29 the
run as a user starts it (:mod:`benchmarks.bench_small`, its processes included) spent
29.7 s of processor time where this one counted 24.2 s; 14 of its 21 pools only found the
linearisations current (now read without a pool: :func:`kisscal.session.linearise.linearise`).

The last line runs the session again over the ``out/`` the first run left (a user's
second ``kisscal run``): stage figures whose PNG was drawn from the same function, data
and code are kept (:func:`kisscal.session.figures.figure_key`). 2026-11-29, main b96d99b
against the stage figures' keys (commit 5ed348f and its successor), two cores shared at a
load of about 10: first run 40.19 s (11.81x decode) -> 38.75 s (13.23x; the decode
reference 3.40 s -> 2.93 s), figures 7.29 -> 7.05 s; run again 15.38 s (4.52x decode)
-> 11.99 s (4.09x), its figures 3.36 s -> 0.46 s (the gait figure only: its stage
removes it before it recomputes). Every PNG, JSON, CSV, TOML and NPZ byte-identical
apart from summary.json's timings and the OpenCV export of cam1 (``cameras.toml``,
``exports.json``), which differs between two runs of main itself (a ``kisscal run`` and
this benchmark's run: rms 0.00223011 against 0.00223059 px, the rational coefficients
k1 0.505 against 0.554): its 19-parameter fit stops in a flat valley where rounding moves
it. An analytic Jacobian for that fit (Rodrigues' and the lens' derivatives, checked
against finite differences to 3e-11) took no time off (7.5 s against 6.4 s for the six
cameras) and moved the rational coefficients along the valley (k1 0.5 -> -27.4, same
rms within 0.0013 px): not kept.

Stop 41 (2026-11-29, load 14 to 17, main aaba448 then this version): whole run 20.61 s
(10.34x decode, 1.99 s) -> 18.56 s (9.12x, 2.04 s); exports 3.60 -> 2.22 s (1.81x ->
1.09x: the fits' Jacobian recomputes per column only what its parameter moves, the same
numbers), imports 1.25 -> 0.87 s (0.63x -> 0.43x: no scipy.signal, hence no
scipy.stats); run again over its ``out/`` 5.81 -> 4.63 s (its calibration's exports are
fitted again). The other parts unchanged (figures 3.81 and 3.77 s, detection 2.92 and
3.02 s); every output byte-identical. With the local background's median by OpenCV's
filter too (load 15): whole run 18.14 s (8.09x decode, 2.24 s), survey 0.60 s, the rest
of calibrate 1.15 s (1.77 and 1.68 before), detection 2.97 s; run again 4.14 s.

Stop 42 (2026-11-29, ``python -m benchmarks small_parts``, main 5f7b3c0 and this branch
in turns, load 11 to 23, decode 1.97-2.05 s): whole run, main 19.33, 19.42, 18.69 and
18.03 s; this branch 18.47 and 18.48 s (the first two changes below), then 17.29 and
18.05 s (all three). DLT (rods), main 2.00, 1.93, 1.95, 1.90 s; this branch 1.61, 1.58,
then 1.13, 1.17 s (0.96x -> 0.58x decode): the lens terms L12..L16 without array
overhead (:func:`kisscal.dlt.lens.distort_xy`: no stacking, one lens's coefficients as
scalars, no unused derivative), and the refinement's forward-difference Jacobian with
its moved points evaluated together (``kisscal.dlt.nonlinear._forward_jacobian``,
scipy's 2-point numbers value for value: the 228 refinements of this session 1.3-1.9 ->
0.61 s, each result bit-identical). Figures, main 3.87, 3.94, 3.73, 3.56 s; this branch
3.63, 3.68, 3.44, 3.66 s: the DLT residual figure (11 x 8.4 in at 90 dpi) was drawn twice,
its Agg canvas 756 px high where the size in inches times dpi, truncated, said 755, so
the palette PNG took matplotlib's PNG path and drew it again (0.57 -> 0.39 s alone; the
size is now the canvas's). Every JSON, CSV, TOML, C3D, TRC, NPZ and PNG of ``out/``
byte-identical in every turn (summary.json's timings aside). What is left: figures 1.8x
(tick creation 0.6 s and tick/text drawing most of it), detection 1.4x, exports 1.2x,
image reading 0.8x, tracking 0.8x, the rest of calibrate 0.6x, DLT on the rods 0.6x,
imports 0.45x.

Stop 43: a ``kisscal run`` with one worker detects no trial ahead
(:mod:`kisscal.session.ahead` needs a second process), so this benchmark's parts, all in
one process, are what they were; :mod:`benchmarks.bench_small` reads the run's wall time
on two free cores.
"""

from __future__ import annotations

import contextlib
import importlib
import os
import shutil
import time
from collections import defaultdict
from collections.abc import Iterator
from pathlib import Path

from benchmarks.bench_pipeline import _decode
from benchmarks.bench_small import BAR, _synthesised

#: (module, function, part) timed; parts nest inside the stages (STAGE lines).
PARTS = (
    ("kisscal.session.stages", "linearise", "STAGE linearise"),
    ("kisscal.session.stages", "calibrate", "STAGE calibrate"),
    ("kisscal.session.stages", "reconstruct", "STAGE reconstruct"),
    ("kisscal.session.stages", "track", "STAGE track"),
    ("kisscal.session.run", "validate", "STAGE validate"),
    ("kisscal.session.run", "summarise", "STAGE summary"),
    ("kisscal.session.run", "report", "STAGE report"),
    ("kisscal.session.figures", "draw_figure", "figures (stage figures)"),
    ("kisscal.detect.sequence", "detect_frames", "detection (stacked frames)"),
    ("kisscal.io.frames", "read_image", "image reading (decode)"),
    ("kisscal.session.configure", "configure_detection", "detection set-up (survey)"),
    ("kisscal.session.linearise", "linearise_frames", "grid fit"),
    ("kisscal.session.routes.rods", "calibrate_rods", "DLT (rods)"),
    ("kisscal.session.calibrate", "write_exports", "exports (cameras.toml fits)"),
    ("kisscal.session.reconstruct", "reconstruct_trial", "reconstruction"),
    ("kisscal.session.track", "build_trajectories", "tracking and labelling"),
    ("kisscal.session.track", "gait_outputs", "gait"),
)


@contextlib.contextmanager
def _timed_parts(spent: dict[str, float], inclusive: dict[str, float]) -> Iterator[None]:
    """Every function of :data:`PARTS` adds its processor time to ``inclusive`` and,
    less the time of the parts called inside it, to ``spent`` meanwhile (so that the
    ``spent`` values add up to the whole)."""
    saved, stack = [], []
    for module_name, name, part in PARTS:
        module = importlib.import_module(module_name)
        original = getattr(module, name)

        def wrapped(*args, _f=original, _part=part, **kwargs):
            stack.append(0.0)  # processor time of the parts inside this call
            t0 = time.process_time()
            try:
                return _f(*args, **kwargs)
            finally:
                elapsed = time.process_time() - t0
                inner = stack.pop()
                spent[_part] += elapsed - inner
                inclusive[_part] += elapsed
                if stack:
                    stack[-1] += elapsed

        saved.append((module, name, original))
        setattr(module, name, wrapped)
    try:
        yield
    finally:
        for module, name, original in saved:
            setattr(module, name, original)


def _run_here(
    root: Path, spent: dict[str, float], inclusive: dict[str, float], fresh: bool = True
) -> float:
    """``kisscal run root`` in this process, from scratch (``fresh``) or again over its
    ``out/``; its processor time."""
    import kisscal.session.figures as figures
    from kisscal.session.run import run

    pool = figures.worker_pool
    figures.worker_pool = lambda *_args: None  # figures drawn here, not in a background process
    if fresh:
        shutil.rmtree(root / "out", ignore_errors=True)
    try:
        with _timed_parts(spent, inclusive):
            t0 = time.process_time()
            run(root, workers=1)
            return time.process_time() - t0
    finally:
        figures.worker_pool = pool


def main() -> list[str]:
    default = Path.home() / ".cache" / "kisscal" / "bench-small"
    root = _synthesised(Path(os.environ.get("KISSCAL_BENCH_SMALL", default)))
    images = sorted(
        p for p in root.rglob("*.png") if p.relative_to(root).parts[0] in ("grid", "rods", "trials")
    )
    _decode(images)  # the files into the page cache, as the run finds them
    t0 = time.process_time()
    _decode(images)
    decode = time.process_time() - t0
    spent: dict[str, float] = defaultdict(float)
    inclusive: dict[str, float] = defaultdict(float)
    t0 = time.process_time()
    import kisscal.cli  # the command line's imports, as a user pays them
    import kisscal.session.run  # noqa: F401

    spent["imports"] = time.process_time() - t0
    whole = _run_here(root, spent, inclusive) + spent["imports"]
    spent["other (run, outside any stage)"] = whole - sum(spent.values())
    lines = [
        f"default synthetic KISS session: {len(images)} images, one process, processor time",
        f"  decode (cv2.imread, one process) {decode:7.2f} s",
        f"  whole run                        {whole:7.2f} s  {whole / decode:5.2f}x decode"
        f" (bar: {BAR:g}x)",
        "  parts (a stage's line: what its listed parts leave):",
    ]
    for part, seconds in sorted(spent.items(), key=lambda kv: -kv[1]):
        lines.append(
            f"  {part:32s} {seconds:7.2f} s  {seconds / decode:5.2f}x decode"
            f"  {100 * seconds / whole:5.1f} %"
        )
    stages = [(p, s) for p, s in inclusive.items() if p.startswith("STAGE")]
    lines.append("  stages, all included: " + ", ".join(f"{p[6:]} {s:.1f} s" for p, s in stages))
    again: dict[str, float] = defaultdict(float)
    rerun = _run_here(root, again, defaultdict(float), fresh=False)
    figures = again["figures (stage figures)"]
    lines.append(
        f"  run again over its out/: {rerun:7.2f} s  {rerun / decode:5.2f}x decode, "
        f"of which figures {figures:.2f} s"
    )
    return lines
