"""Reconstruction and labelling with 2 and 3 cameras: subsets of the synthetic rigs.

Truth-level scenario (:func:`tests.recon.scenario.observe`: true centroids + 0.05 px noise,
the other cameras' LEDs, two noise blobs per camera and field, markers closer than 3 px
in an image merged into one blob) of the kinematic gait trial, seen by every 2- and
3-camera subset of a rig. Per subset: recall of the markers seen by >= 2 cameras (and of
those whose blobs survived merging in >= 2 cameras), ghost points, points by number of
cameras, and the labelled trajectories (``kisscal.tracking`` with the trial's marker set;
"of": the markers that >= 2 cameras see in at least ``min_track_length`` fields).

Run ``python -m tests.recon.subsets [seed ...]`` from the repository root.
"""

from __future__ import annotations

import itertools
import sys
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.recon import Points3D, ReconParams, reconstruct_trial
from kisscal.synth.evaluate import score_trajectories
from kisscal.tracking import TrackingParams, build_trajectories

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
    points: Points3D, xyz: NDArray[np.float64], radius_mm: float = 10.0
) -> tuple[NDArray[np.bool_], int]:
    """Per (field, marker), whether a point lies within ``radius_mm``; and the ghost count."""
    found = np.zeros(xyz.shape[:2], dtype=bool)
    ghosts = 0
    for f in np.unique(points.field):
        P = points.xyz_mm[points.field == f]
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
) -> SubsetScore:
    t0 = time.perf_counter()
    pts = reconstruct_trial(tab.field, tab.camera, tab.uv, dlts, params)
    seconds = time.perf_counter() - t0
    found, ghosts = found_and_ghosts(pts, xyz)
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
        np.asarray(["measured", "predicted", "filled"])[tracks.status],
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


def kiss_subsets(
    seed: int,
    subsets: list[tuple[int, ...]] | None = None,
    n_fields: int = 200,
    params: ReconParams | None = None,
) -> list[SubsetScore]:
    """Camera subsets (default: every 2- and 3-camera one) of the six-camera KISS-like
    rig of ``seed``."""
    from kisscal.synth.cameras import kiss_rig
    from kisscal.synth.motion import standing_template, walking_trial
    from kisscal.synth.scene import visibility

    params = params or ReconParams()
    rig = kiss_rig(seed)
    motion = walking_trial(seed, n_fields, n_markers=15)
    visible = np.stack([visibility(cam, motion) for cam in rig], axis=-1)
    dlts = np.array([cam.dlt for cam in rig])
    marker_set = (motion.names, standing_template(motion.names), motion.segments)
    if subsets is None:
        subsets = [c for n in (2, 3) for c in itertools.combinations(range(len(rig)), n)]
    out = []
    for cams in subsets:
        sub = list(cams)
        tab = observe(dlts[sub], rig[0].size_px, motion.xyz_mm, visible[..., sub], seed)
        out.append(
            score_subset(cams, tab, dlts[sub], motion.xyz_mm, visible[..., sub], marker_set, params)
        )
    return out


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


def main(seeds: tuple[int, ...] = (1, 2, 3)) -> list[str]:
    lines = [HEADER]
    summary: dict[int, list[SubsetScore]] = {2: [], 3: []}
    for seed in seeds:
        for s in kiss_subsets(seed):
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
    print("\n".join(main(tuple(int(a) for a in sys.argv[1:]) or (1, 2, 3))))
