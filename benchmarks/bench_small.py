"""A small session: ``python -m kisscal run`` on the default synthetic KISS session against
decoding its images, both timed in the same run (issue 28: within 2x on all cores).

The session is ``kisscal synth`` with its defaults (the KISS preset, seed 1: 6 cameras of
752 x 291 px, trials walk01, stick, throw and the replayed walk5, about 4000 PNG files),
synthesised once into a cache folder (a few minutes) and reused. What a session of that
size costs beyond its images is start-up: processes, the calibration exports, figures and
the report, which every session pays whatever its length.

Reference: reading and decoding every image the run reads (``cv2.imread``, as kisscal's
reader) in a process pool on all cores, after a pass that brings the files into the page
cache. ``python -m kisscal run`` then runs in a child process from scratch (``out/``
removed): interpreter start-up and imports count, as they do for a user. Its stage
timings come from its ``summary.json``.

Both are also given as processor time (user + system, the process and its children): on a
machine shared with other work the wall-clock ratio moves with the load, the processor
time much less.

Recorded (2026-11-29, 4044 images, 2 cores shared with 8 other sessions at a load of 8
to 22, where wall-clock ratios are not worth reading; processor time, the run's and its
processes'): main ddf3077 12.41x decode (29.7 s against 2.4 s), this version 11.72x
(25.3 s against 2.2 s), 25 minutes apart; run against main in turns under the same load,
0.97x main's processor time (25.7 and 26.2 s against 26.6 and 26.7 s). 14 worker pools
of the run (28 forked processes) were started only to find the grid linearisations
current (every ``current_rig`` of calibrate, reconstruct and track); they are now read
in the run's process (0.05 -> 0.015 s of processor time and 0.44 -> 0.10 s of wall a
call). The exports' six OpenCV fits (a sixth of the run's processor time) now go side by
side to the pool (``each_camera``): the same processor time, half the wall time of that
step on two free cores (116 -> 56 s for the six on the loaded machine). Every JSON, CSV,
TOML, C3D, TRC, NPZ and PNG of ``out/`` byte-identical; ``summary.json`` and
``report.html`` differ by their timings, and the figures' ``.key`` files by the source
they hash. What is left, as multiples of decoding in one process
(:mod:`benchmarks.bench_small_parts`): figures 1.9x, exports 1.7x, detection 1.4x, image
reading 0.85x, DLT on the rods 0.8x, the rest of calibrate 0.85x, imports 0.6x
(scipy.signal for the gait's Savitzky-Golay derivative brings scipy.stats: 0.2x),
tracking 0.6x.

Stop 41 (2026-11-29, ``python -m benchmarks small``, main aaba448 and this branch in
turns, 2 cores at a load of 14 to 18): processor time of the run, main 25.0, 24.9, 25.4
and 25.2 s, this branch 22.7 and 23.7 s (exports and imports below), then 21.1 and
23.2 s (and the local background's median); decode 2.1-2.2 s in every turn but the last
two of this branch (1.3 and 1.4 s, so their ratios, 15.7x and 17.1x, say nothing: 10.0x
and 11.0x against 2.1 s). The exports' six fits take their forward-difference Jacobian
column by column, recomputing only what each parameter moves
(:class:`kisscal.opencv._ExportResiduals`: scipy's numbers, so the same fits; 4.2 ->
2.6-2.9 s for the six in one process); the gait's Savitzky-Golay derivative no longer
imports scipy.signal, nor scipy.stats with it (:func:`kisscal.gait.signals.savgol_slope`;
the command line's imports 1.35 -> 1.00 s); the local background's 5 x 5 median is
OpenCV's median filter (``kisscal.detect.background._rank5``, 12 -> 0.26 ms on a 73 x
188 map). Every JSON, CSV, TOML, C3D, TRC, NPZ and PNG of ``out/`` byte-identical between
a ``kisscal run`` of main and of this branch. What is left
(:mod:`benchmarks.bench_small_parts`): figures 1.6x, detection 1.3x, exports 1.0x
(MINPACK's own steps are 60 % of it), image reading 0.8x, DLT on the rods 0.7x, the rest
of calibrate 0.5x, imports 0.4x, tracking 0.4x.

Stop 42 (2026-11-29, ``python -m benchmarks small``, main 5f7b3c0 then this branch, load
about 23, where the wall clock (81 and 67 s) says nothing): processor time of the run
23.0 -> 22.0 s (decode 1.4 and 1.3 s: 16.9x and 16.4x). The DLT's refinement evaluates
its Jacobian's moved points together and its lens terms without array overhead (DLT on
the rods 1.9 -> 1.15 s in :mod:`benchmarks.bench_small_parts`), the DLT residual figure
is drawn once instead of twice. Every JSON, CSV, TOML, C3D, TRC, NPZ and PNG of ``out/``
byte-identical. The bar's "on both cores" read as wall time against decoding on every
core: the figures are already drawn in a background process beside the stages, so on
two free cores their 3.5 s of processor time is mostly off the run's wall time; the
processor time, which does not move with the load, is the measure used here.

Stop 43 (2026-11-29, ``python -m benchmarks small``, this branch and main 585b09b in
turns, load 20 to 25 with this session's tests running): the bar's "on both cores" is
read as the run's wall time on the machine's two cores, free, against decoding on both.
On a machine shared with eight sessions the wall clock gives a run a share of the cores
that moves with the others' load (decode 7.8-17.4 s where it takes 1.1 s free), so the
run's wall time on two free cores is now read from its parallelism profile
(:class:`benchmarks._cores.TreeSampler`: every 20 ms the runnable processes of the run's
tree and their processor time; each moment's work over the cores its runnable processes
could use), and decoding's as its processor time over the cores (its pool is parallel
throughout). Main: 14.1 and 14.4 s on two free cores, 13.48x and 13.38x decode (processor
time 22.0 and 22.5 s; wall under the load 154 and 152 s); this branch 11.8 and 12.3 s,
11.06x and 11.63x (processor time 20.2 and 21.1 s; wall 123 and 97 s). ``farm-bench``
pairing the two benchmarks, decode included (3 pairs, load about 21): wall 0.961x and processor time
0.970x main's (medians 95.2 s against 99.0 s, 24.1 s against 24.9 s). What changed: most
of what follows detection runs in one process (the calibration's DLT, each trial's
reconstruction and tracking), and the other core waited; ``kisscal run`` now derives the
markers' settings once the grid's are known and detects every trial's images in a
background pool from there (:mod:`kisscal.session.ahead`), so that pool detects the next
trials beside the calibration and the trials' stages, and a trial takes its blobs from
it (the same blobs, cached as before). By the profile, the time a core sat idle (the
free-core wall less half the processor time) was 2.9 s of 13.4 s and is 1.9 s of 12.2 s
(one profile each): the imports at the start (1.3 s in one process), the last trial's
tracking and the report after it (that trial's figures are drawn then, 0.8 s), the rest
scattered. Two free cores cannot bring the run below its processor-time ratio (9.5-10x
decode, the decode itself being parallel throughout): the bar asks for a fifth of
today's processor time, not for more of the second core. Every JSON,
CSV, TOML, C3D, TRC, NPZ and PNG of ``kisscal demo``'s ``out/`` byte-identical; a session
with an unreadable trial image fails that trial with the same message and the same other
outputs.

Stop 44 (2026-11-30, the trials bundle's cost, issue 25's default; load 20 to 28, main
7e2041c): ``python -m benchmarks small`` once each, main 24.8 s of processor time
(11.54x decode), 15.8 s on two free cores (14.70x); this branch (with the refits in the
pool, reverted below) 24.9 s, 14.8 s (14.02x): within the noise, as are the turns
below. Where the bundle's time goes, by
processor time in the run's process (calibrate of the bench session, blobs cached):
4.6 s with the bundle against 1.4 s without; of the bundle's 3.0 s, the adjustment with
its outlier pass 1.1 s, its leave-one-rod-out refits (four adjustments) 0.9 s, the rods'
second, pinhole fit 0.6 s, the trials' table 0.4 s. Inside the six adjustments
(cProfile, processor time): the Schur step's ``W V^-1 W^T`` a third (its (camera,
field) grid filled, then one product per two cameras), Jacobian einsums and segment
sums a fifth; Jacobian, line search and resection little. Kept, every number
bit-identical: the grid allocated once per problem instead of every damped step, no
segment sum over pairs of one observation (free points); the six adjustments 1.52 ->
1.36 s; the rods' pinhole fit made before the trials' table, so it runs while the
background detection still has the other core (its 0.6 s was on one core after it).
Tried and not kept, measured: (1) OpenBLAS on one thread (``OPENBLAS_NUM_THREADS=1``
for the whole run): processor time 24.7 s against 24.8 s, two free cores 15.8 s against
15.8 s, calibrate 12.86 s against 12.89 s in one process: although a 1000 x 12 SVD
costs 0.14 ms on one thread and 50 ms on two on this loaded machine, the run's LAPACK
calls are too few to show (stop 43 replaced the one that did, the bundle's LU); (2)
the four leave-one-rod-out refits side by side in the pool
(``each_camera``, the same arrays bit for bit): farm-bench 3 pairs of ``kisscal run``,
processor time 1.024x main's (sys 2.27 -> 2.72 s), two free cores 17.78 and 17.20 s
against main's 16.81 and 17.52 s in turns: no gain above the noise, reverted. By the
parallelism profile (one run of this branch, 14.5 s on two free cores) one core idles
4.9 s: 1.25 s from the trials' table to the bundle's end (one adjustment after the
other), 1.1 s from there to the first trial (the figures, the exports' unevenly long
fits), 1.4 s in the last trial's tracking and the report, the rest in start-up. The trials'
reconstruction and tracking side by side (candidate 3) was not tried: the static trial
goes first, the blobs detected ahead are held by the run's process, and the trials'
messages and failures must keep their order. Every JSON, CSV, TOML, C3D, TRC and NPZ of
``kisscal demo``'s ``out/`` byte-identical; ``python -m tests.session.lens_trial_bundle
kiss:71:...`` the same numbers to the last digit.

Stop 46 (2026-11-30, main 8646c56 and this branch in turns, load 12 to 17): where the
run's processor time goes, sampled in every process of one run (``setitimer`` profiling,
a sample every 2 ms of processor time, 24.1 s in all): the figures' process 4.4 s
(Agg's drawing 3.1 s, most of it the axes' ticks, created, labelled and measured, and
text; building the figures 0.6 s; importing matplotlib 0.4 s), the run's own process
10.2 s, the trials detected ahead 4.9 s, the markers' survey 2.1 s, the exports' fits
1.7 s. In the run's own process a trial's frames were listed and keyed again and again
(336 listings of a camera's frames, 200 files each, and the keys of those files): 1.0 s
of its 10.2 s. Kept, the same keys and listings: ``is_image_file`` no longer rebuilds
each path, a key takes a file's path inside the session from its parts
(``relative_to`` parsed the root again for each of 4000 files), ``trials_key`` lists
each trial once (it listed it three times), and an image trial's files are not checked
a second time (its listing holds only files): listing the four trials 0.064 -> 0.037 s,
the keys of their files 0.048 -> 0.021 s. Whole ``kisscal run``, 4 pairs timed from
outside in turns: processor time 0.978x main's (medians 22.4 s against 23.0 s);
``python -m benchmarks small`` in turns: main 23.7 and 22.2 s (11.28x and 10.86x
decode), this branch 22.4 and 22.3 s (10.59x and 10.62x): the gain, about 0.5 s, is
within one run's noise. Every JSON, CSV, TOML, C3D, TRC, NPZ, PNG and cache key of
``out/`` byte-identical (``summary.json`` and ``report.html`` differ by their timings,
the figures' ``.key`` files by the source they hash). The figures are left as they are:
22 % of the ticks matplotlib creates lie outside the view (created and labelled, never
drawn; keeping only those in view hands the tick formatter other locations, which can
change a label), and a figure drawn a second time takes 0.5 to 0.8 of its first drawing
(ticks and text metrics kept), so reusing one figure per kind would save at most about
0.4 s (the six grid and four trajectory figures) for clearing every artist, limit and
aspect by hand.

Stop 49 (2026-11-30, main 3e34862 and this branch, load 11 to 27 on the two cores):
``python -m benchmarks small`` on main, one run: decode 2.3 s of processor time, the run
88.7 s (37.9x; 44.0x on two free cores, wall 59x): under that load a run's processor time
itself doubles (the same main ``kisscal run`` 49 s at 14:10, 55 s in farm-bench turns,
where the stop-46 record is 22-23 s), so no ratio of this stop is worth reading against
the 10.6x of stop 46. farm-bench, two pairs of ``kisscal run`` (this branch against main,
in turns): processor time 0.79x and 1.29x (median 1.04x): the changes below are under the
noise of a whole run on this machine and are argued by their own timings. Where the
time goes (cProfile of ``run(root, workers=1)`` in one process, wall-clock under the
load): figures 28 % (Agg's ticks and text most of it), the calibration's rods-and-trials
bundle with its leave-one-rod-out refits 9 %, the exports' fits 6.5 %, the surveys 6 %,
the grid fits 8 %, tracking 8 %, the window moments of detection 5 %, decoding 3.4 %.
Kept: (1) the window moments place each pixel in its window by repeats, not an integer
divmod per pixel (10.6 -> 5.7 ms for 750k window pixels, the same integers; the blobs of
200 frames bit-identical); (2) ``kisscal run`` lists each camera's frame folder once
(:func:`kisscal.io.frames.listing_once`: validation, surveys, cache keys and detection
listed them 312 times, ``frame_paths`` 1.5 % of the run in one process), and an image is
opened without a stat first. Every JSON, CSV, TOML, C3D, TRC, NPZ and PNG of ``out/``
byte-identical to main's (two session copies; the ``.key`` files differ by the copies'
file times, ``summary.json`` and ``report.html`` by timings). Issue 28's bar (the run
within 2x decode on both cores) is out of reach of plain costs: the run reads every
image (0.8x the decode) and detects it (1.4x, stop 42's parts), 2.2x before calibration,
tracking, figures and the interpreter's start.

Stop 57 (2026-12-01, main 1317951 and this branch, load 9 to 15 on the two cores): the
command line now gives the BLAS libraries one thread per process
(:mod:`kisscal.cli.blas`; stop 44 tried it and did not keep it), and this harness runs
with it (``python -m benchmarks``). NumPy, SciPy and OpenCV each load an OpenBLAS of two
threads here; under this load a 1000 x 12 SVD took 0.13 ms on one thread and a median of
0.26-68 ms on two, and 900 small calls 0.6 s of processor time against 8.6-18 s (the
waiting threads spin). The run itself makes too few such calls to show it: whole
``kisscal run`` in turns with main, two rounds of three pairs, processor time 0.954x and
1.034x main's (medians 23.2 against 24.5 s, 25.8 against 25.0 s), wall 0.91x and 1.24x;
``python -m benchmarks small`` in turns, main 25.0 and 26.2 s of processor time (13.7x
and 14.4x decode), this branch 25.5 and 27.4 s (17.1x and 17.8x: its decode reference,
run with one BLAS thread too, took 1.5 s against main's 1.8 s). Every JSON, CSV, TOML,
C3D, TRC, NPZ and PNG of ``out/`` byte-identical. Where the time goes
(:mod:`benchmarks.bench_small_parts`, one process, decode 1.71 s): the rest of calibrate
3.2x decode (its largest piece the rods-and-trials bundle, adjustment and
leave-one-rod-out refits: 3.0 s of calibrate's 20.0 s under cProfile), figures 2.5x
(Agg's ticks most of it), detection 2.2x, tracking 1.35x, exports 1.2x, image reading
1.05x, DLT on the rods 0.8x, imports 0.5x: reading and detecting the images alone are
3.2x the decode, above issue 28's 2x.

Environment: ``KISSCAL_BENCH_SMALL`` the cache folder (default
``~/.cache/kisscal/bench-small``).
"""

from __future__ import annotations

import json
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

from benchmarks._cores import TreeSampler
from benchmarks._harness import Timing, report
from benchmarks.bench_pipeline import _decode, _decode_all

#: Issue 28's bar: the run within this many times the decode time.
BAR = 2.0


def _synthesised(folder: Path) -> Path:
    """The cached default synthetic session, made on the first call."""
    root = folder / "kiss-seed1"
    if (root / "session.toml").is_file():
        return root
    from kisscal.session.synth import synthesise

    print(f"synthesising {root} (once; a few minutes)", flush=True)
    shutil.rmtree(root, ignore_errors=True)
    synthesise(root)
    return root


def _children_cpu_s() -> float:
    """Processor time (user + system) of the finished child processes so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _run(root: Path, n_images: int, cores: int) -> tuple[Timing, dict, float]:
    """``python -m kisscal run root`` from scratch in a child process; its wall time on
    ``cores`` free cores as well, from its parallelism profile
    (:class:`benchmarks._cores.TreeSampler`)."""
    shutil.rmtree(root / "out", ignore_errors=True)
    t0 = time.perf_counter()
    child = subprocess.Popen(
        [sys.executable, "-m", "kisscal", "run", str(root)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    sampler = TreeSampler(child.pid)
    sampler.start()
    _out, err = child.communicate()
    seconds = time.perf_counter() - t0
    sampler.stop()
    if child.returncode != 0:
        raise RuntimeError(f"kisscal run {root} failed:\n{err[-2000:]}")
    summary = json.loads((root / "out" / "summary.json").read_text())
    timing = Timing("python -m kisscal run", seconds, n_images, "images")
    return timing, summary, sampler.free_wall(cores)


def main() -> list[str]:
    default = Path.home() / ".cache" / "kisscal" / "bench-small"
    root = _synthesised(Path(os.environ.get("KISSCAL_BENCH_SMALL", default)))
    images = sorted(
        p for p in root.rglob("*.png") if p.relative_to(root).parts[0] in ("grid", "rods", "trials")
    )
    cores = os.cpu_count() or 1
    _decode(images)  # the files into the page cache, as the run finds them
    cpu0 = _children_cpu_s()
    decode = _decode_all(images, cores)
    cpu1 = _children_cpu_s()
    run, summary, free = _run(root, len(images), cores)
    cpu2 = _children_cpu_s()
    cpu_decode, cpu_run = cpu1 - cpu0, cpu2 - cpu1
    stages = ", ".join(f"{k[:-2]} {v:.1f}" for k, v in summary["timings"].items())
    return [
        f"default synthetic KISS session: {len(images)} images; {cores} cores",
        "  " + report(decode),
        "  " + report(run, decode) + f" (bar: {BAR:g}x)",
        f"  processor time: decode {cpu_decode:.1f} s, run {cpu_run:.1f} s, "
        f"ratio {cpu_run / cpu_decode:.2f}x",
        f"  on {cores} free cores (from the parallelism profile): decode "
        f"{cpu_decode / cores:.2f} s, run {free:.1f} s, ratio {free * cores / cpu_decode:.2f}x",
        f"  stages (s): {stages}",
    ]
