"""Issue 27's "done when" table: small labs, whole trajectories (not a test; run it).

    python -m tests.tracking.few_cameras_acceptance [seed ...]          # rigs table
    python -m tests.tracking.few_cameras_acceptance [seed] --gaps       # fill methods
    python -m tests.tracking.few_cameras_acceptance 101 --rig=lowcost   # one kind of rig
    python -m tests.tracking.few_cameras_acceptance --merge=first       # old merge model
    python -m tests.tracking.few_cameras_acceptance --no-hidden         # recon/hidden.py off
    python -m tests.tracking.few_cameras_acceptance --no-held           # deblend_held off

Default seeds 301-303, held out (development used 1-7; 101-103 were looked at while
the body fill was built). Rigs: ``kisscal synth --preset lowcost``
(4 cameras), ``--preset kiss --cameras 3`` and ``--preset modern --cameras 3``, and the
full kiss (6) and modern (8) rigs for "unchanged"; each walk made long enough to cross the
volume (:data:`FIELDS`). Scenario: :mod:`tests.recon.scenario`'s truth-level one (true
centroids + 0.05 px noise, other cameras' LEDs, two noise blobs per camera and field,
markers closer than 3 px merged into one blob at their area-weighted centroid, as a
detector does; ``--merge=first`` puts it at the first marker's image instead) plus
blobs a camera loses beside the body's own occlusions (:func:`dropouts`: 0.2 runs a
second per marker and camera, 0.1-1 s long), so
that markers drop to two or fewer cameras for up to a second, as with real detection.
Reconstructed (with the marker set's rigid triangles, :mod:`kisscal.recon.body`) and
tracked with default settings and the trial's marker set (the 2D
blobs no 3D point used go to single-camera fill; ``score_trial(..., rays=False)`` without), scored
against truth: recall of markers seen by exactly two cameras, ghosts, coverage of each
marker's span (first to last field seen by >= 3 cameras) by samples of the trajectory
bearing its name within 20 mm (min and mean over markers), RMS error of filled samples,
names right (of the markers two cameras see in at least ``min_track_length`` fields),
identity switches (measured samples nearer another marker than their name's), filled
samples whose true error is over twice their fill's expected error (and of those, over
3 mm): fills whose expectation is not honest. The gap
table: rigid-body fill (three markers, or two and a lab direction), pattern and spline
fill, and the per-gap choice, against truth on gaps of 0.2 to 2 s cut into each marker of
the true walk.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.io.points2d import observation_points
from kisscal.recon import ReconParams, reconstruct_trial
from kisscal.recon.body import RigidTriangles
from kisscal.tracking import (
    MEASURED,
    PREDICTED,
    SpareBlobs,
    TrackingParams,
    build_trajectories,
    spare_blobs,
)
from tests.recon.scenario import observe
from tests.recon.subsets import found_and_ghosts


@dataclass(frozen=True)
class RigTrial:
    """One trial seen by a camera subset, with its truth."""

    preset: str
    seed: int
    cameras: tuple[int, ...]
    field: NDArray[np.int64]
    xyz_mm: NDArray[np.float64]
    truth: NDArray[np.float64]
    visible: NDArray[np.bool_]
    names: tuple[str, ...]
    template_mm: NDArray[np.float64]
    segments: tuple
    rate_hz: float
    n_points: int
    ghosts: int
    found: NDArray[np.bool_]
    spare: SpareBlobs


#: Where the scenario puts a merged blob (:func:`tests.recon.scenario.observe`'s ``merge``).
MERGE = ["centroid"]

#: Reconstruction settings of every trial (``--no-hidden``: without the markers merged in
#: one view placed by a rigid segment, :mod:`kisscal.recon.hidden`, on by default).
RECON = [ReconParams()]

#: Fields of the walk per preset: long enough to cross the volume (cut to the fields inside).
FIELDS = {"kiss": 400, "modern": 600, "lowcost": 400}


def dropouts(
    shape: tuple[int, ...], rate_hz: float, seed: int, per_s: float = 0.2, longest_s: float = 1.0
) -> NDArray[np.bool_]:
    """Blobs a camera loses beside the body's occlusions (merges, a reflection, a marker
    turned away): for each (marker, camera), runs starting ``per_s`` times a second on
    average, each 0.1 s to ``longest_s`` long. Shape (n_fields, n_markers, n_cameras)."""
    rng = np.random.default_rng([seed, 2727])
    n_fields = shape[0]
    lost = np.zeros(shape, dtype=bool)
    starts = rng.random(shape) < per_s / rate_hz
    for f, m, c in zip(*np.nonzero(starts), strict=True):
        n = int(rng.uniform(0.1, longest_s) * rate_hz)
        lost[f : min(f + n, n_fields), m, c] = True
    return lost


def rig_trial(
    preset: str, seed: int, n_cameras: int | None = None, merge: str | None = None
) -> RigTrial:
    """Reconstruct the walk of ``kisscal synth --preset <preset> --seed <seed> --cameras
    <n_cameras>`` (default: the preset's cameras) from the truth-level scenario, merged
    blobs placed as ``merge`` says (default :data:`MERGE`)."""
    from kisscal.synth.plan import plan_session
    from kisscal.synth.presets import synth_options
    from kisscal.synth.scene import visibility

    plan = plan_session(synth_options(preset, seed, fields=FIELDS[preset], n_cameras=n_cameras))
    rig, motion = plan.rig, plan.trials["walk01"]
    cams = list(range(len(rig)))
    visible = np.stack([visibility(rig[c], motion) for c in cams], axis=-1)
    visible &= ~dropouts(visible.shape, motion.rate_hz, seed)
    dlts = np.array([rig[c].dlt for c in cams])
    tab = observe(dlts, rig[0].size_px, motion.xyz_mm, visible, seed, merge=merge or MERGE[0])
    body = RigidTriangles.from_marker_set(plan.marker_names, plan.template_mm, plan.segments)
    pts = reconstruct_trial(tab.field, tab.camera, tab.uv, dlts, RECON[0], motion.rate_hz, body)
    found, ghosts = found_and_ghosts(pts.field, pts.xyz_mm, motion.xyz_mm)
    # the blobs no point used, and those of the points, each with its point's row
    point = observation_points(pts.blob_row, len(tab.field))
    rows = ((pts.marker < 0) & ~pts.stationary) | (point >= 0)
    spare = spare_blobs(tab.field[rows], tab.camera[rows], tab.uv[rows], dlts, point[rows])
    return RigTrial(
        preset,
        seed,
        tuple(cams),
        pts.field,
        pts.xyz_mm,
        motion.xyz_mm,
        visible,
        tuple(plan.marker_names),
        np.asarray(plan.template_mm),
        tuple(plan.segments),
        float(motion.rate_hz),
        len(pts.field),
        ghosts,
        found,
        spare,
    )


@dataclass(frozen=True)
class TrialScore:
    recall2: float
    ghost_fraction: float
    coverage_min: float
    coverage_mean: float
    rmse_filled_mm: float
    labelled: int
    n_markers: int
    labellable: int
    switches: int
    seconds: float
    filled_by: dict[str, int]
    dishonest: tuple[int, int] = (0, 0)


def track_trial(trial: RigTrial, params: TrackingParams | None = None, rays: bool = True):
    """Track ``trial`` with its marker set; with ``rays`` the unused blobs go to
    single-camera fill."""
    return build_trajectories(
        trial.field,
        trial.xyz_mm,
        params,
        trial.names,
        trial.template_mm,
        trial.segments,
        rate_hz=trial.rate_hz,
        spare=trial.spare if rays else None,
    )


def score_trial(
    trial: RigTrial, params: TrackingParams | None = None, rays: bool = True
) -> TrialScore:
    """Track ``trial`` with its marker set and score it against truth (see module); with
    ``rays``, the unused blobs go to single-camera fill."""
    from kisscal.tracking import STATUS_NAMES

    t0 = time.perf_counter()
    res = track_trial(trial, params, rays)
    seconds = time.perf_counter() - t0
    n_seen = trial.visible.sum(axis=2)
    exactly2 = n_seen == 2
    truth = trial.truth
    tr = res.tracks
    n_fields, n_markers = truth.shape[:2]
    err = np.full(tr.field.size, np.inf)
    own = np.full(tr.field.size, -1)
    label_of = np.asarray(res.labels, dtype=object)[tr.track]
    for j, name in enumerate(trial.names):
        rows = label_of == name
        own[rows] = j
    ok = own >= 0
    err[ok] = np.linalg.norm(tr.xyz_mm[ok] - truth[tr.field[ok], own[ok]], axis=1)
    # identity switches: measured samples nearer another marker than their own name's
    switches = 0
    for f in np.unique(tr.field[ok & (tr.status == MEASURED)]):
        rows = np.flatnonzero(ok & (tr.status == MEASURED) & (tr.field == f))
        d = np.linalg.norm(tr.xyz_mm[rows, None] - truth[f][None], axis=2)
        d = np.where(np.isfinite(d), d, np.inf)
        switches += int(np.sum(d.argmin(axis=1) != own[rows]))
    covered = np.zeros((n_fields, n_markers), dtype=bool)
    good = ok & (tr.status != PREDICTED) & (err < 20.0)
    covered[tr.field[good], own[good]] = True
    cov = []
    for j in range(n_markers):
        seen3 = np.flatnonzero(n_seen[:, j] >= 3)
        if seen3.size == 0:
            continue
        cov.append(covered[seen3[0] : seen3[-1] + 1, j].mean())
    filled = ok & (tr.status >= 2) & np.isfinite(err)
    # dishonest fills: true error over twice their expected error (and over 3 mm)
    over = filled & (err > 2.0 * _expected_per_sample(res.fills, tr, n_fields))
    names = np.asarray(STATUS_NAMES)
    by = {str(n): int(np.sum(ok & (tr.status == k))) for k, n in enumerate(names) if k >= 2}
    labelled = sum(
        1
        for name in trial.names
        if name in res.labels and np.any((label_of == name) & (err < 20.0))
    )
    return TrialScore(
        float(trial.found[exactly2].mean()) if exactly2.any() else float("nan"),
        trial.ghosts / max(trial.n_points, 1),
        float(np.min(cov)),
        float(np.mean(cov)),
        float(np.sqrt(np.mean(err[filled] ** 2))) if filled.any() else 0.0,
        labelled,
        n_markers,
        int(np.sum((n_seen >= 2).sum(axis=0) >= TrackingParams().min_track_length)),
        switches,
        seconds,
        by,
        (int(np.sum(over)), int(np.sum(over & (err > 3.0)))),
    )


def _expected_per_sample(fills, tr, n_fields: int) -> NDArray[np.float64]:
    """Each sample's expected error: its gap fill's (``fills``, GapFill), NaN where no
    fill placed it (a sample whose true error is over twice it is dishonestly filled)."""
    table = np.full((tr.n_tracks, n_fields), np.nan)
    for g in fills:
        table[g.track, g.first_field : g.first_field + g.n_fields] = g.expected_error_mm
    return table[tr.track, tr.field]


RIGS = {
    "lowcost 4": ("lowcost", None),
    "kiss 3": ("kiss", 3),
    "modern 3": ("modern", 3),
    "kiss 6": ("kiss", None),
    "modern 8": ("modern", None),
}

HEADER = (
    "| rig | seed | recall, seen by 2 | ghosts | coverage of span (min / mean) "
    "| filled RMS (mm) | over 2x expected (> 3 mm) | labelled (of seen) | switches "
    "| filled spline/rigid/pattern | s |"
)


def rows(seeds: tuple[int, ...], rigs: dict = RIGS) -> list[str]:
    out = [HEADER, "|" + "---|" * 11]
    for name, (preset, cams) in rigs.items():
        for seed in seeds:
            trial = rig_trial(preset, seed, cams)
            s = score_trial(trial)
            fb = "/".join(str(v) for v in s.filled_by.values())
            out.append(
                f"| {name} | {seed} | {100 * s.recall2:.2f} % | {100 * s.ghost_fraction:.2f} % "
                f"| {100 * s.coverage_min:.2f} / {100 * s.coverage_mean:.2f} % "
                f"| {s.rmse_filled_mm:.2f} | {s.dishonest[0]} ({s.dishonest[1]}) "
                f"| {s.labelled}/{s.n_markers} ({s.labellable}) "
                f"| {s.switches} | {fb} | {s.seconds:.1f} |"
            )
            print(out[-1], flush=True)
    return out


GAPS_S = (0.2, 0.5, 1.0, 2.0)


def gap_table(preset: str, seed: int, noise_mm: float = 0.5, n_cuts: int = 4) -> list[str]:
    """Rigid-body, pattern and spline fill against truth on gaps of :data:`GAPS_S` cut into
    every marker of the walk (all others measured, ``noise_mm`` noise per axis), at
    ``n_cuts`` places each: RMS error (mm) over the gaps each method could fill, and in
    how many of them it could."""
    from kisscal.synth.plan import plan_session
    from kisscal.synth.presets import synth_options
    from kisscal.tracking.bodyfill import (
        axis_fill,
        best_candidate,
        fill_candidates,
        pattern_fill,
        rigid_fill,
    )
    from kisscal.tracking.fill_spline import spline_fill

    plan = plan_session(synth_options(preset, seed, fields=FIELDS[preset]))
    motion = plan.trials["walk01"]
    xyz = motion.xyz_mm[np.all(np.isfinite(motion.xyz_mm), axis=(1, 2))]
    rng = np.random.default_rng([seed, 27])
    dense = (xyz + rng.normal(0, noise_mm, xyz.shape)).transpose(1, 0, 2)
    params = TrackingParams()
    methods = {
        "rigid": rigid_fill,
        "two-marker": axis_fill,
        "pattern": pattern_fill,
        "spline": spline_fill,
    }
    out = [
        f"{preset} seed {seed}, {motion.rate_hz:.0f} Hz, {dense.shape[1]} fields, "
        f"{noise_mm} mm noise",
        "| gap (s) | rigid RMS (filled/tried) | two-marker | pattern | spline | chosen per gap |",
        "|---|---|---|---|---|---|",
    ]
    for gap_s in GAPS_S:
        n = round(gap_s * motion.rate_hz)
        err: dict[str, list] = {k: [] for k in [*methods, "chosen"]}
        tried = 0
        for j in range(dense.shape[0]):
            room = dense.shape[1] - n - 2 * params.body_context_fields
            for lo in np.linspace(params.body_context_fields, room, n_cuts).astype(int):
                tried += 1
                cut = dense.copy()
                cut[j, lo : lo + n] = np.nan
                truth = xyz[lo : lo + n, j]
                for name, method in methods.items():
                    got = method(cut[j], cut, j, lo, lo + n, params)
                    if got is not None:
                        err[name].append(np.sum((got[0] - truth) ** 2, axis=1))
                best = best_candidate(fill_candidates(cut, j, lo, lo + n, params), params)
                if best is not None:
                    err["chosen"].append(np.sum((best.xyz_mm - truth) ** 2, axis=1))
        cells = [
            f"{np.sqrt(np.mean(np.concatenate(e))):.2f} mm ({len(e)}/{tried})" if e else "-"
            for e in err.values()
        ]
        out.append(f"| {gap_s} | " + " | ".join(cells) + " |")
    return out


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    seeds = tuple(int(a) for a in args) or (301, 302, 303)
    only = next((a.split("=", 1)[1] for a in sys.argv if a.startswith("--rig=")), None)
    rigs = {k: v for k, v in RIGS.items() if only is None or k.startswith(only)}
    MERGE[0] = next((a.split("=", 1)[1] for a in sys.argv if a.startswith("--merge=")), MERGE[0])
    if "--no-hidden" in sys.argv or "--no-held" in sys.argv:
        RECON[0] = ReconParams(
            deblend_hidden="--no-hidden" not in sys.argv, deblend_held="--no-held" not in sys.argv
        )
    if "--gaps" in sys.argv:
        for preset in ("kiss", "modern", "lowcost"):
            print("\n".join(gap_table(preset, seeds[0])))
    else:
        print("\n".join(rows(seeds, rigs)))
