"""Does one correct extra 3D point make tracking worse? (issue 27; not a test, run it).

    python -m tests.tracking.extra_point_probe 301 --rig="kiss 3" [--n=8] [--any] [--all]
    python -m tests.tracking.extra_point_probe 301 --rig="kiss 3" --at=RANK@49,LHEE@107
    python -m tests.tracking.extra_point_probe 301 --rig="kiss 3" --at=LANK@340,LHEE@340 --together

Reconstructs the walk of :mod:`tests.tracking.few_cameras_acceptance` (kept in
/tmp/extra_point_probe_*.pkl: delete them after changing reconstruction), then, one at
a time, inserts the TRUE position (+0.5 mm noise per axis) of a marker the
reconstruction missed at one field (of those two cameras saw; ``--any``: one camera or
more), and tracks again with default settings. Per insertion: identity switches and
names right (as the acceptance table scores them) and, to tell which stage made a
change, the samples of track pieces that mix two markers after tracking (``raw``) and
after blending (``blend``), and the measured samples whose label names another marker
after labelling (``wrong``). A correct point must never make any of them worse. With
``--all``, every missed point at once (as a perfect two-camera reconstruction would);
with ``--together``, the ``--at`` points at once.
"""

from __future__ import annotations

import dataclasses
import pickle
import sys
from pathlib import Path

import numpy as np

from kisscal.tracking import MEASURED, TrackingParams
from kisscal.tracking.blending import blend_tracks
from kisscal.tracking.pipeline import _label
from kisscal.tracking.tracker import track_points
from tests.tracking.few_cameras_acceptance import RIGS, RigTrial, rig_trial, score_trial


def cached_trial(preset: str, seed: int, cams: int | None) -> RigTrial:
    """The reconstructed trial, kept in /tmp between runs (reconstruction is slow)."""
    path = Path(f"/tmp/extra_point_probe_{preset}_{cams}_{seed}.pkl")
    if path.exists():
        return pickle.loads(path.read_bytes())
    trial = rig_trial(preset, seed, cams)
    path.write_bytes(pickle.dumps(trial))
    return trial


def owner(trial: RigTrial, field, xyz, radius_mm: float = 20.0):
    """Nearest true marker of each sample (-1 when none within ``radius_mm``)."""
    d = np.linalg.norm(xyz[:, None] - trial.truth[field], axis=2)
    d = np.where(np.isfinite(d), d, np.inf)
    best = d.argmin(axis=1)
    return np.where(d.min(axis=1) <= radius_mm, best, -1)


def mixed(trial: RigTrial, tracks) -> int:
    """Measured samples of pieces not of the piece's most frequent marker."""
    m = tracks.status == MEASURED
    own = owner(trial, tracks.field[m], tracks.xyz_mm[m])
    tr = tracks.track[m]
    n = 0
    for t in np.unique(tr):
        o = own[tr == t]
        o = o[o >= 0]
        if o.size:
            n += int(o.size - np.bincount(o).max())
    return n


def wrong(trial: RigTrial, labelling) -> int:
    """Measured samples whose label is another marker's name."""
    tracks = labelling.tracks
    m = tracks.status == MEASURED
    own = owner(trial, tracks.field[m], tracks.xyz_mm[m])
    index = {n: j for j, n in enumerate(trial.names)}
    lab = np.array([index.get(s, -1) for s in labelling.labels])[tracks.track[m]]
    return int(np.sum((lab >= 0) & (own >= 0) & (lab != own)))


def stages(trial: RigTrial) -> dict[str, int]:
    """Mixed samples after tracking and blending, wrong ones after labelling, and the
    acceptance score's switches and names right."""
    params = TrackingParams()
    raw = track_points(trial.field, trial.xyz_mm, params)
    blended = blend_tracks(raw, params)
    lab = _label(
        blended, params, trial.names, trial.template_mm, trial.segments, None, trial.rate_hz
    )
    s = score_trial(trial)
    return {
        "raw": mixed(trial, raw),
        "blend": mixed(trial, blended),
        "wrong": wrong(trial, lab),
        "switches": s.switches,
        "names": s.labelled,
    }


def with_point(trial: RigTrial, f: int, j: int, rng) -> RigTrial:
    """``trial`` with marker ``j``'s true position (+0.5 mm noise) added at field ``f``."""
    xyz = trial.truth[f, j] + rng.normal(0, 0.5, 3)
    field = np.r_[trial.field, f]
    order = np.argsort(field, kind="stable")
    return dataclasses.replace(
        trial,
        field=field[order],
        xyz_mm=np.r_[trial.xyz_mm, xyz[None]][order],
        n_points=trial.n_points + 1,
    )


def candidates(trial: RigTrial, n: int, seed: int, seen2: bool = True) -> list[tuple[int, int]]:
    """``n`` (field, marker) the reconstruction missed while two cameras saw the marker
    (any marker in view with ``seen2`` False)."""
    seen = trial.visible.sum(axis=2)
    miss = ~trial.found & np.all(np.isfinite(trial.truth), axis=2)
    miss &= (seen == 2) if seen2 else (seen >= 1)
    f, j = np.nonzero(miss)
    rng = np.random.default_rng(seed)
    pick = rng.choice(f.size, size=min(n, f.size), replace=False)
    return [(int(f[k]), int(j[k])) for k in sorted(pick)]


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    seed = int(args[0]) if args else 301
    opt = dict(a[2:].split("=", 1) for a in sys.argv[1:] if a.startswith("--") and "=" in a)
    preset, cams = next(v for k, v in RIGS.items() if k.startswith(opt.get("rig", "kiss 3")))
    trial = cached_trial(preset, seed, cams)
    base = stages(trial)
    print(f"base: {base}", flush=True)
    todo = candidates(trial, int(opt.get("n", 8)), seed, "--any" not in sys.argv)
    if "at" in opt:
        todo = []
        for item in opt["at"].split(","):
            name, f = item.split("@")
            todo.append((int(f), trial.names.index(name)))
    rng = np.random.default_rng([seed, 39])
    if "--together" in sys.argv:  # the --at points at once (several may break what one cannot)
        every = trial
        for f, j in todo:
            every = with_point(every, f, j, rng)
        got = stages(every)
        print(f"together {len(todo)}: {got}  change { {k: got[k] - base[k] for k in got} }")
        todo = []
    if "--all" in sys.argv:  # every missed point at once: a perfect two-camera recall
        todo = candidates(trial, 10**9, seed, "--any" not in sys.argv)
        every = trial
        for f, j in todo:
            every = with_point(every, f, j, rng)
        got = stages(every)
        print(f"all {len(todo)}: {got}  change { {k: got[k] - base[k] for k in got} }")
        todo = []
    for f, j in todo:
        got = stages(with_point(trial, f, j, rng))
        diff = {k: got[k] - base[k] for k in got}
        print(f"{trial.names[j]}@{f}: {got}  change {diff}", flush=True)
