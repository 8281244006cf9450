"""Labelling speed on real C3D files (issue 26): every raw marker of a file tracked and
named from the Plug-in Gait set alone, as the regression table does
(:func:`tests.io.c3d_acceptance.label_raw`).

Files: walking5.c3d (shipped), and from the C3D cache (``KISSCAL_C3D_CACHE``) test1.c3d
and pyCGM's Movement_trial.c3d, each skipped (one line) when absent. Reference, timed in
the same run on the same points in turns (CPU time, one run each): the thesis' basic
nearest-neighbour linking (:func:`benchmarks.bench_tracking.nearest_neighbour_linking`).

Stop 55 (issue 26: minutes per file), before -> after: ``farm-bench`` pairs in one run
(A = s55-labspeed, B = main 9966019, taken in turns; whole process, CPU seconds; 2 cores
shared with up to ten other jobs: walking5 and Movement_trial wall seconds were 3-4
times these; test1 ran on a quiet machine, wall = CPU):

=====================  =========  =========  ======
file                   main       branch     ratio
=====================  =========  =========  ======
test1.c3d              92.9 s     40.8 s     0.44
Movement_trial.c3d     19.7 s     13.1 s     0.66
walking5.c3d           11.1 s     9.2 s      0.83
=====================  =========  =========  ======

The label rows of all three were identical to main's in every run.
"""

from __future__ import annotations

import time

from benchmarks._harness import best_of_pair, report
from benchmarks.bench_tracking import nearest_neighbour_linking
from kisscal.io.c3d import read_c3d
from tests.io import c3d_acceptance as A

FILES = ("walking5.c3d", "test1.c3d", "Movement_trial.c3d")


def main() -> list[str]:
    lines, cache = [], A.cache_folder(None)
    for name in FILES:
        path = A.find(name, cache)
        if path is None:
            lines.append(f"{name}: skipped, not in {cache}")
            continue
        c3d = read_c3d(path)
        field, xyz, _ = A.shuffled(c3d.xyz_mm)
        ref, ours = best_of_pair(
            (
                "nearest-neighbour linking (cKDTree)",
                lambda f=field, p=xyz: nearest_neighbour_linking(f, p),
            ),
            ("label_raw (track + name)", lambda c=c3d: A.label_raw(c, "plug-in-gait-full")),
            int(field.max()) + 1,
            "fields",
            repeat=1,
            clock=time.process_time,
        )
        lines += [f"{name}: {c3d.xyz_mm.shape[1]} channels", report(ref), report(ours, ref)]
    return lines
