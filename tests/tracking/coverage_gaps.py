"""Why issue 27's coverage falls short: each missing sample of a marker's span, classified
(not a test; run it).

    python -m tests.tracking.coverage_gaps 303 --rig=lowcost
    python -m tests.tracking.coverage_gaps 301 313 --rig="kiss 3"

A sample of a marker's span (first to last field seen by >= 3 cameras) is missing when
the trajectory bearing its name has no sample within 20 mm of truth there
(:func:`tests.tracking.few_cameras_acceptance.score_trial`). Each is put in one class:

* ``end``: before the named trajectory's first measured sample or after its last (the
  fill only works inside a trajectory);
* ``wrong``: the trajectory has a sample there but it is 20 mm or more off (``wrong
  measured`` / ``wrong filled``);
* ``open``: inside the trajectory, no sample: a gap fill left open (with its length);
* and, across the classes, whether a 3D point of the trial lay within 20 mm of truth
  (``point``), not in the named trajectory, and how many cameras saw the marker.
"""

from __future__ import annotations

import sys
from collections import Counter

import numpy as np

from kisscal.tracking import MEASURED, PREDICTED
from tests.tracking.few_cameras_acceptance import RIGS, rig_trial, track_trial


def classify(trial, params=None) -> tuple[Counter, list[str]]:
    """Missing samples of ``trial`` per class, and one line per open gap."""
    res = track_trial(trial, params)
    tr, truth = res.tracks, trial.truth
    n_seen = trial.visible.sum(axis=2)
    labels = np.asarray(res.labels, dtype=object)
    counts: Counter = Counter()
    lines = []
    for j, name in enumerate(trial.names):
        seen3 = np.flatnonzero(n_seen[:, j] >= 3)
        if seen3.size == 0:
            continue
        span = np.arange(seen3[0], seen3[-1] + 1)
        rows = np.flatnonzero(labels[tr.track] == name)
        err = np.full(truth.shape[0], np.inf)
        status = np.full(truth.shape[0], -1)
        keep = tr.status[rows] != PREDICTED
        r = rows[keep]
        err[tr.field[r]] = np.linalg.norm(tr.xyz_mm[r] - truth[tr.field[r], j], axis=1)
        status[tr.field[r]] = tr.status[r]
        meas = tr.field[rows[tr.status[rows] == MEASURED]]
        lo, hi = (meas.min(), meas.max()) if meas.size else (np.inf, -np.inf)
        miss = span[~(err[span] < 20.0)]
        # a 3D point of the trial near truth in that field
        d = np.linalg.norm(trial.xyz_mm - truth[trial.field, j], axis=1)
        near = np.zeros(truth.shape[0], dtype=bool)
        near[trial.field[d < 20.0]] = True
        for f in miss:
            where = "end" if f < lo or f > hi else ("wrong" if status[f] >= 0 else "open")
            if where == "wrong":
                where += " measured" if status[f] == MEASURED else " filled"
            pt = "point" if near[f] else f"no point ({min(n_seen[f, j], 3)} cams)"
            counts[(where, pt)] += 1
        # open gaps and ends, as runs
        bad = np.zeros(truth.shape[0], dtype=bool)
        bad[miss] = True
        edges = np.flatnonzero(np.diff(np.r_[0, bad.astype(int), 0]))
        for a, b in zip(edges[::2], edges[1::2], strict=True):
            kind = "end" if a < lo or a > hi else ("wrong" if status[a] >= 0 else "open")
            cams = np.bincount(np.minimum(n_seen[a:b, j], 3), minlength=4)
            lines.append(
                f"  {name:6s} {kind:5s} fields {a}-{b - 1} ({b - a}) traj {lo}-{hi} "
                f"span {span[0]}-{span[-1]} cams0-3 {cams.tolist()} points {near[a:b].sum()}"
            )
    return counts, lines


if __name__ == "__main__":
    seeds = [int(a) for a in sys.argv[1:] if not a.startswith("--")] or [301]
    only = next((a.split("=", 1)[1] for a in sys.argv if a.startswith("--rig=")), "lowcost")
    for rig, (preset, cams) in RIGS.items():
        if not rig.startswith(only):
            continue
        for seed in seeds:
            counts, lines = classify(rig_trial(preset, seed, cams))
            print(f"{rig} {seed}: {sum(counts.values())} missing")
            for k, v in counts.most_common():
                print(f"  {v:5d} {k[0]} / {k[1]}")
            print("\n".join(lines), flush=True)
