"""Reconstruction and labelling with 2 and 3 cameras: subsets of the synthetic rigs.

Truth-level scenario (:func:`tests.recon.scenario.observe`: true centroids + 0.05 px noise,
the other cameras' LEDs, two noise blobs per camera and field, markers closer than 3 px
in an image merged into one blob) of the kinematic gait trial, seen by every 2- and
3-camera subset of a rig. Per subset: recall of the markers seen by >= 2 cameras (and of
those whose blobs survived merging in >= 2 cameras), ghost points, points by number of
cameras, and the labelled trajectories (``kisscal.tracking`` with the trial's marker set;
"of": the markers that >= 2 cameras see in at least ``min_track_length`` fields).

Run ``python -m tests.recon.subsets [seed ...] [--preset=kiss|modern|lowcost]`` from the
repository root. With ``--sessions``, the same from images instead: ``kisscal synth
--cameras 2`` and ``3`` sessions (the synthetic rig's own first cameras) run through
``kisscal run``, their ``points3d.csv`` scored against ``truth/`` and their trajectories
by :func:`kisscal.session.evaluate`.
"""

from __future__ import annotations

import itertools
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from kisscal.recon import ReconParams, reconstruct_trial
from kisscal.synth.evaluate import score_trajectories
from kisscal.tracking import STATUS_NAMES, TrackingParams, build_trajectories

from .scenario import Table2D, observe


@dataclass(frozen=True)
class SubsetScore:
    """How a camera subset reconstructs and labels the gait trial."""

    cameras: tuple[int, ...]
    n_seen2: int
    n_seen2_blobs: int
    n_found: int
    n_found_blobs: int
    n_points: int
    n_ghosts: int
    points_by_n_cameras: tuple[int, ...]
    labelled: int
    labellable: int
    n_markers: int
    switches: int
    seconds: float

    @property
    def recall(self) -> float:
        """Of the markers that >= 2 cameras see."""
        return self.n_found / max(self.n_seen2, 1)

    @property
    def recall_blobs(self) -> float:
        """Of the markers with a blob of their own in >= 2 cameras (merged blobs aside)."""
        return self.n_found_blobs / max(self.n_seen2_blobs, 1)

    @property
    def ghost_fraction(self) -> float:
        return self.n_ghosts / max(self.n_points, 1)


def found_and_ghosts(
    field: NDArray[np.int64],
    xyz_mm: NDArray[np.float64],
    xyz: NDArray[np.float64],
    radius_mm: float = 10.0,
) -> tuple[NDArray[np.bool_], int]:
    """Per (field, true marker), whether a point (``field``, ``xyz_mm``) lies within
    ``radius_mm`` of it; and the number of points near no true marker (ghosts)."""
    found = np.zeros(xyz.shape[:2], dtype=bool)
    ghosts = 0
    for f in np.unique(field):
        P = xyz_mm[field == f]
        d = np.linalg.norm(P[:, None] - xyz[f][None], axis=2)
        d[:, ~np.all(np.isfinite(xyz[f]), axis=1)] = np.inf
        ghosts += int((d.min(axis=1) > radius_mm).sum())
        found[f] = d.min(axis=0) <= radius_mm
    return found, ghosts


def score_subset(
    cameras: tuple[int, ...],
    tab: Table2D,
    dlts: NDArray[np.float64],
    xyz: NDArray[np.float64],
    visible: NDArray[np.bool_],
    marker_set: tuple[tuple[str, ...], NDArray[np.float64], tuple],
    params: ReconParams,
    rate_hz: float = 50.0,
) -> SubsetScore:
    t0 = time.perf_counter()
    pts = reconstruct_trial(tab.field, tab.camera, tab.uv, dlts, params, rate_hz)
    seconds = time.perf_counter() - t0
    found, ghosts = found_and_ghosts(pts.field, pts.xyz_mm, xyz)
    seen2 = visible.sum(axis=2) >= 2
    own = np.zeros_like(visible)
    real = tab.truth >= 0
    own[tab.field[real], tab.truth[real], tab.camera[real]] = True
    seen2_blobs = seen2 & (own.sum(axis=2) >= 2)
    names, template, segments = marker_set
    traj = build_trajectories(pts.field, pts.xyz_mm, None, names, template, segments)
    tracks = traj.tracks
    f_true, m_true = np.nonzero(np.all(np.isfinite(xyz), axis=2))
    lab = score_trajectories(
        tracks.field,
        np.asarray(traj.labels, dtype=object)[tracks.track].astype(str),
        tracks.xyz_mm,
        np.asarray(STATUS_NAMES)[tracks.status],
        f_true,
        np.asarray(names)[m_true],
        xyz[f_true, m_true],
        seen2[f_true, m_true],
    )
    return SubsetScore(
        cameras,
        int(seen2.sum()),
        int(seen2_blobs.sum()),
        int((found & seen2).sum()),
        int((found & seen2_blobs).sum()),
        len(pts),
        ghosts,
        tuple(np.bincount(pts.n_cameras, minlength=len(cameras) + 1)[2:].tolist()),
        lab.correctly_labelled,
        int(np.sum(seen2.sum(axis=0) >= TrackingParams().min_track_length)),
        lab.n_true_markers,
        lab.identity_switches,
        seconds,
    )


def rig_subsets(
    preset: str,
    seed: int,
    subsets: list[tuple[int, ...]] | None = None,
    n_fields: int | None = None,
    params: ReconParams | None = None,
) -> list[SubsetScore]:
    """Camera subsets (default: every 2- and 3-camera one) of the rig that
    ``kisscal synth --preset <preset> --seed <seed>`` draws (its default cameras)."""
    from kisscal.synth.plan import plan_session
    from kisscal.synth.presets import synth_options
    from kisscal.synth.scene import visibility

    params = params or ReconParams()
    plan = plan_session(synth_options(preset, seed, fields=n_fields))
    rig, motion = plan.rig, plan.trials["walk01"]
    visible = np.stack([visibility(cam, motion) for cam in rig], axis=-1)
    dlts = np.array([cam.dlt for cam in rig])
    marker_set = (plan.marker_names, plan.template_mm, plan.segments)
    if subsets is None:
        subsets = [c for n in (2, 3) for c in itertools.combinations(range(len(rig)), n)]
    out = []
    for cams in subsets:
        sub = list(cams)
        tab = observe(dlts[sub], rig[0].size_px, motion.xyz_mm, visible[..., sub], seed)
        score = score_subset(
            cams,
            tab,
            dlts[sub],
            motion.xyz_mm,
            visible[..., sub],
            marker_set,
            params,
            motion.rate_hz,
        )
        out.append(score)
    return out


def kiss_subsets(
    seed: int,
    subsets: list[tuple[int, ...]] | None = None,
    n_fields: int = 200,
    params: ReconParams | None = None,
) -> list[SubsetScore]:
    """Camera subsets of the six-camera KISS-like rig of ``seed`` (:func:`rig_subsets`)."""
    return rig_subsets("kiss", seed, subsets, n_fields, params)


HEADER = (
    "seed cameras      recall2%  (own blobs)  ghost%  points  by 2/3 cams   labelled  (of)"
    "  switches"
)


def row(seed: int, s: SubsetScore) -> str:
    cams = ",".join(str(c + 1) for c in s.cameras)
    by = "/".join(str(n) for n in s.points_by_n_cameras)
    return (
        f"{seed:4d} cam{cams:10s} {100 * s.recall:8.2f}  ({100 * s.recall_blobs:7.2f})"
        f"  {100 * s.ghost_fraction:6.2f}  {s.n_points:6d}  {by:12s}  {s.labelled:3d}/{s.n_markers}"
        f"  ({s.labellable:2d})  {s.switches:8d}"
    )


def true_markers(root: Path, trial: str) -> tuple[np.ndarray, np.ndarray]:
    """A synthetic session's true marker positions (fields, markers, 3; NaN where absent)
    and by how many cameras each is seen (fields, markers)."""
    from kisscal.io.files import read_table

    truth = read_table(root / "truth" / "trials" / trial / "markers.csv")
    names = list(dict.fromkeys(truth["marker"].tolist()))
    f = truth["field"].astype(int)
    j = np.array([names.index(m) for m in truth["marker"]])
    xyz = np.full((f.max() + 1, len(names), 3), np.nan)
    xyz[f, j] = np.column_stack([truth["x_mm"], truth["y_mm"], truth["z_mm"]]).astype(float)
    seen = np.zeros((f.max() + 1, len(names)), dtype=int)
    seen[f, j] = sum(truth[k].astype(int) for k in truth if k.startswith("visible_"))
    return xyz, seen


def score_session(root: Path, trial: str = "walk01") -> tuple[float, float, int, list[int]]:
    """Recall of markers seen by >= 2 cameras, ghost fraction, points, points by cameras
    of a processed synthetic session's trial (its ``points3d.csv`` against ``truth/``)."""
    from kisscal.io.points3d import read_points3d

    xyz, seen = true_markers(root, trial)
    pts = read_points3d(root / "out" / "trials" / trial / "points3d.csv")
    found, ghosts = found_and_ghosts(pts.field, pts.xyz_mm, xyz)
    seen2 = seen >= 2
    by_n = np.bincount(pts.n_cameras, minlength=pts.blob.shape[1] + 1)[2:].tolist()
    return (
        (found & seen2).sum() / max(seen2.sum(), 1),
        ghosts / max(len(pts.field), 1),
        len(pts.field),
        by_n,
    )


def sessions(seeds: tuple[int, ...], work: Path, preset: str = "kiss") -> list[str]:
    """``kisscal synth --preset <preset> --cameras 2|3`` sessions of each seed, run and
    scored (see module)."""
    from kisscal import session

    lines = [
        f"preset {preset}",
        "seed cameras  recall2%  ghost%  points  by 2/3 cams   labelled  switches  run_s",
    ]
    for seed in seeds:
        for n in (2, 3):
            root = work / f"s{seed}c{n}"
            session.synthesise(
                root, preset=preset, seed=seed, n_cameras=n, walking5=False, force=True
            )
            t0 = time.perf_counter()
            try:
                session.run(root)
            except Exception as exc:  # report the session and go on with the others
                lines.append(f"{seed:4d} {n:7d}  run failed: {type(exc).__name__}: {exc}")
                continue
            seconds = time.perf_counter() - t0
            recall, ghost, n_points, by_n = score_session(root)
            walk = session.evaluate(root)["walk01"]
            lines.append(
                f"{seed:4d} {n:7d}  {100 * recall:8.2f}  {100 * ghost:6.2f}  {n_points:6d}"
                f"  {'/'.join(map(str, by_n)):12s}  {walk['correctly_labelled']:3d}/"
                f"{walk['n_true_markers']}  {walk['identity_switches']:8d}  {seconds:5.0f}"
            )
    return lines


def main(seeds: tuple[int, ...] = (1, 2, 3), preset: str = "kiss") -> list[str]:
    lines = [f"preset {preset}", HEADER]
    summary: dict[int, list[SubsetScore]] = {2: [], 3: []}
    for seed in seeds:
        for s in rig_subsets(preset, seed):
            lines.append(row(seed, s))
            summary[len(s.cameras)].append(s)
    for n, scores in summary.items():
        ok = [s for s in scores if s.recall >= 0.98 and s.ghost_fraction <= 0.01]
        full = [s for s in scores if s.labelled == s.n_markers]
        lines.append(
            f"{n} cameras: {len(ok)}/{len(scores)} subsets with recall >= 98 % and ghosts <= 1 %;"
            f" {len(full)}/{len(scores)} with every marker labelled; median recall"
            f" {100 * np.median([s.recall for s in scores]):.2f} %, median ghosts"
            f" {100 * np.median([s.ghost_fraction for s in scores]):.2f} %"
        )
    return lines


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    seeds = tuple(int(a) for a in args) or (1, 2, 3)
    preset = next((a.split("=", 1)[1] for a in sys.argv if a.startswith("--preset=")), "kiss")
    if "--sessions" in sys.argv:
        with tempfile.TemporaryDirectory() as tmp:
            print("\n".join(sessions(seeds, Path(tmp), preset)))
    else:
        print("\n".join(main(seeds, preset)))
