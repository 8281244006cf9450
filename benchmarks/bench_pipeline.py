"""A whole session: ``kisscal run`` on 8 cameras x 1000 fields against decoding its images.

The session is a synthetic modern lab (``kisscal synth --preset modern --fields 1000``,
8 cameras of 1280 x 1024 px), synthesised once into a cache folder (several minutes) and
reused. Two sessions are built from it with symbolic links, each with the grid and rod
images and one trial:

- ``walk1000``: the 1000-field walking trial;
- ``walk2000``: the same frames played forwards then backwards (2000 fields, motion
  continuous), to show that peak memory does not grow with the length of a trial.

Reference, timed in the same run: reading and decoding every image that run reads
(``cv2.imread``, as kisscal's reader), on all cores (a process pool) and on one.
``kisscal run`` runs in a child process from scratch (no ``out/``); its peak memory is
the resident set of that process and of the largest of its detection workers
(``getrusage``). The run's own stage timings come from its ``summary.json``.

Environment: ``KISSCAL_BENCH_PIPELINE`` the cache folder (default
``~/.cache/kisscal/bench-pipeline``), ``KISSCAL_BENCH_FIELDS_PIPELINE`` fields of the
walking trial (default 1000).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import cv2
import tomli_w
import tomllib

from benchmarks._harness import Timing, report

#: Runs a session in a child process and prints its peak memory (kB) as JSON.
_RUN = """
import json, resource, sys
from pathlib import Path
from kisscal.session.run import run
run(Path(sys.argv[1]))
own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
workers = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
print(json.dumps({"main_kb": own, "worker_kb": workers}))
"""


def _synthesised(folder: Path, fields: int) -> Path:
    """The cached synthetic session, made on the first call."""
    source = folder / f"modern-{fields}"
    if (source / "session.toml").is_file():
        return source
    from kisscal.session.synth import synthesise

    print(f"synthesising {source} (once; several minutes)", flush=True)
    shutil.rmtree(source, ignore_errors=True)
    synthesise(source, preset="modern", fields=fields, walking5=False)
    return source


def _session(source: Path, root: Path, backwards: bool) -> list[Path]:
    """A session at ``root`` of ``source``'s grid, rods and walking trial; its images."""
    shutil.rmtree(root, ignore_errors=True)
    root.mkdir(parents=True)
    config = tomllib.loads((source / "session.toml").read_text())
    for folder in ("grid", "rods"):
        (root / folder).symlink_to(source / folder)
    config["trials"] = [{"name": "walk", "images": "trials/walk/{camera}/*.png"}]
    (root / "session.toml").write_text(tomli_w.dumps(config))
    images = sorted((source / "grid").glob("*/*.png")) + sorted((source / "rods").glob("*/*.png"))
    for cam_dir in sorted((source / "trials" / "walk01").iterdir()):
        frames = sorted(cam_dir.glob("*.png"))
        played = frames + frames[::-1] if backwards else frames
        target = root / "trials" / "walk" / cam_dir.name
        target.mkdir(parents=True)
        for k, frame in enumerate(played):
            (target / f"{k:05d}.png").symlink_to(frame)
        images += played
    return images


def _decode(paths: list[Path]) -> int:
    cv2.setNumThreads(1)
    return sum(cv2.imread(str(p), cv2.IMREAD_UNCHANGED).size for p in paths)


def _decode_all(paths: list[Path], workers: int) -> Timing:
    chunks = [paths[i : i + 64] for i in range(0, len(paths), 64)]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(workers) as pool:
        list(pool.map(_decode, chunks))
    return Timing(f"decode, {workers} processes", time.perf_counter() - t0, len(paths), "images")


def _run(root: Path, n_images: int) -> tuple[Timing, dict, dict]:
    t0 = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", _RUN, str(root)], capture_output=True, text=True, check=False
    )
    seconds = time.perf_counter() - t0
    if done.returncode != 0:
        raise RuntimeError(f"kisscal run {root} failed:\n{done.stderr[-2000:]}")
    memory = json.loads(done.stdout.strip().splitlines()[-1])
    summary = json.loads((root / "out" / "summary.json").read_text())
    return Timing(f"kisscal run {root.name}", seconds, n_images, "images"), memory, summary


def main() -> list[str]:
    fields = int(os.environ.get("KISSCAL_BENCH_FIELDS_PIPELINE", "1000"))
    default = Path.home() / ".cache" / "kisscal" / "bench-pipeline"
    folder = Path(os.environ.get("KISSCAL_BENCH_PIPELINE", default))
    source = _synthesised(folder, fields)
    cores = os.cpu_count() or 1
    lines = [f"modern rig, 8 cameras of 1280 x 1024 px, {fields} fields; {cores} cores"]
    peaks = {}
    for name, backwards in ((f"walk{fields}", False), (f"walk{2 * fields}", True)):
        images = _session(source, folder / name, backwards)
        _decode(images[::50])  # the files into the page cache, as the run finds them
        all_cores = _decode_all(images, cores)
        sample = images[:: max(1, len(images) // 400)]
        one = _decode_all(sample, 1)
        lines.append(f"{name}: {len(images)} images (grid, rods, trial)")
        lines.append("  " + report(all_cores))
        lines.append(f"  decode, 1 process: {1e3 * one.seconds / one.items:.2f} ms per image")
        run, memory, summary = _run(folder / name, len(images))
        lines.append("  " + report(run, all_cores) + " (bar: 3x)")
        peaks[name] = memory["main_kb"] + cores * memory["worker_kb"]
        lines.append(
            f"  peak RSS: main {memory['main_kb'] / 1024:.0f} MB, largest worker "
            f"{memory['worker_kb'] / 1024:.0f} MB; main + {cores} workers "
            f"{peaks[name] / 1024:.0f} MB (bar: 1500 MB)"
        )
        stages = ", ".join(f"{k[:-2]} {v:.1f}" for k, v in summary["timings"].items())
        lines.append(f"  stages (s): {stages}")
    short, long = peaks.values()
    lines.append(f"peak RSS {2 * fields} / {fields} fields: {long / short:.2f} (bar: within 1.2)")
    return lines
