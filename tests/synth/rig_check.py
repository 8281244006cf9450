"""A preset's rig through the pipeline with detection parameters derived from its truth.

:func:`check_rig` renders one synthetic rig in memory (no files), detects with the
hand-derived parameters of :mod:`tests.synth.truth_params` (one set per camera and kind of
image), linearises every camera from its grid, calibrates from the rods, and reconstructs
a short walk and the stick trial; it returns the figures the tests assert on and
``python -m tests.synth.presets_table`` prints.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import islice
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from kisscal.detect import detect_blobs
from kisscal.dlt import DltParams, calibrate_rods, make_rods
from kisscal.grid import GridParams, Linearisation, apply_linearisation, linearise_frames
from kisscal.recon import ReconParams, reconstruct_trial
from kisscal.synth.motion import STICK_LENGTH_MM
from kisscal.synth.plan import SynthPlan, plan_session, render_grid, render_rods, render_trial
from kisscal.synth.presets import synth_options
from kisscal.synth.render import SpotSizes
from kisscal.synth.scene import SIZE_LEVELS, FieldTruth
from kisscal.synth.truth import camera_detection_truth, size_ranges
from tests.synth.truth_params import detection_params

#: Reconstruction without the stationary filter: over a dozen fields the stance foot's
#: markers do not move and would be removed (issue 11 item 4); LED rings are already
#: invalid blobs here.
RECON = ReconParams(stationary_filter=False)


@dataclass
class RigFigures:
    """What one rig gave; lists hold one entry per camera."""

    preset: str
    seed: int
    plan: SynthPlan
    truth: list[dict[str, Any]] = field(default_factory=list)
    grid_dots: list[int] = field(default_factory=list)
    grid_rms_px: list[float] = field(default_factory=list)
    rod_markers: list[int] = field(default_factory=list)
    dlt_rms_px: list[float] = field(default_factory=list)
    walk_recall: float = float("nan")
    walk_recall_isolated: float = float("nan")
    walk_ghosts: float = float("nan")
    walk_rmse_mm: float = float("nan")
    walk_reproj_px: float = float("nan")
    stick_mae_mm: float = float("nan")
    notes: list[str] = field(default_factory=list)


def trial_ranges(truths: list[FieldTruth]) -> dict[str, Any]:
    """Size ranges of the whole, isolated markers of one camera's rendered fields."""

    def seen(values: list[NDArray]) -> NDArray:
        return np.concatenate([v[t.visible] for v, t in zip(values, truths, strict=True)])

    sizes = {
        lv: SpotSizes(
            *(
                seen([getattr(t.sizes[lv], k) for t in truths])
                for k in ("width_px", "height_px", "pixels")
            )
        )
        for lv in SIZE_LEVELS
    }
    iso = seen([t.isolated for t in truths]) & np.isfinite(sizes["low"].pixels)
    return size_ranges(2 * seen([t.radii_px for t in truths]), sizes, iso)


def _detect(images: list[NDArray], params: Any, lin: Linearisation) -> list[NDArray]:
    out = []
    for image in images:
        blobs = detect_blobs(image, params).valid_only()
        xy = np.column_stack([blobs.x_px, blobs.y_px])
        out.append(apply_linearisation(lin, xy) if len(xy) else np.zeros((0, 2)))
    return out


def _table(per_camera: list[list[NDArray]]) -> tuple[NDArray, NDArray, NDArray]:
    f, c, uv = [], [], []
    for ci, frames in enumerate(per_camera):
        for k, xy in enumerate(frames):
            f.append(np.full(len(xy), k))
            c.append(np.full(len(xy), ci))
            uv.append(xy)
    return np.concatenate(f).astype(int), np.concatenate(c).astype(int), np.concatenate(uv)


def check_rig(
    preset: str, seed: int, walk_fields: int = 12, stick_fields: int = 12, **options: Any
) -> RigFigures:
    """Render, detect (truth-derived parameters), linearise, calibrate, reconstruct."""
    plan = plan_session(synth_options(preset, seed, fields=max(walk_fields, 10), **options))
    fig = RigFigures(preset, seed, plan)
    walk, stick, rods, alone = [], [], {}, []
    for ci, cam in enumerate(plan.rig):
        shots = list(render_trial(plan, "walk01", ci))[:walk_fields]
        alone.append(np.array([t.isolated for _, _, t in shots]))
        truth = camera_detection_truth(plan, ci, trial_ranges([t for _, _, t in shots]))
        fig.truth.append(truth)
        params = {}
        for kind in ("grid", "rods", "trials"):
            params[kind], notes = detection_params(truth, kind, plan.render.blur_px)
            fig.notes += notes
        grid = linearise_frames(render_grid(plan, ci)[0], GridParams(), params["grid"])
        lin = grid.linearisation
        fig.grid_dots.append(int(grid.index.n_indexed))
        fig.grid_rms_px.append(float(lin.quality.residual_rms_after_px))
        rods[cam.id] = _detect(render_rods(plan, ci)[0], params["rods"], lin)
        walk.append(_detect([im for _, im, _ in shots], params["trials"], lin))
        # the first fields only: the kiss preset's stick trial is 200 fields long
        sticks = [im for _, im, _ in islice(render_trial(plan, "stick", ci), stick_fields)]
        stick.append(_detect(sticks, params["trials"], lin))
    rod_list = make_rods([(r.name, r.points_mm) for r in plan.rods])
    cal = calibrate_rods(rods, rod_list, DltParams(), leave_one_out=False)
    L = np.stack([cal.results[c.id].L for c in plan.rig])
    fig.rod_markers = [len(cal.labels[c.id]) for c in plan.rig]
    fig.dlt_rms_px = [float(cal.results[c.id].rms_px) for c in plan.rig]
    _score_walk(fig, plan, _table(walk), L, np.stack(alone, axis=-1))
    fig.stick_mae_mm = _stick_error(plan, _table(stick), L, stick_fields)
    return fig


def _seen(plan: SynthPlan, trial: str, n_fields: int) -> tuple[NDArray, NDArray]:
    """True marker positions and how many cameras see each, over the first fields."""
    from kisscal.synth.plan import trial_visibility

    xyz = plan.trials[trial].xyz_mm[:n_fields]
    vis = trial_visibility(plan, trial)[:n_fields].sum(axis=-1)
    return xyz, vis


def _score_walk(
    fig: RigFigures, plan: SynthPlan, table: tuple, L: NDArray, isolated: NDArray
) -> None:
    """Recall (a point within 10 mm) of markers seen by >= 3 cameras and of those seen
    whole and alone by >= 3 (``isolated``, (F, M, C)), ghosts, 3D RMSE, reprojection."""
    points = reconstruct_trial(*table, L, RECON)
    xyz, vis = _seen(plan, "walk01", len(isolated))
    alone = isolated.sum(axis=-1)
    hits = {"seen": [0, 0], "alone": [0, 0]}
    ghosts, errors = 0, []
    for f in range(len(xyz)):
        mine = points.xyz_mm[points.field == f]
        exists = np.isfinite(xyz[f]).all(axis=1)
        near = np.zeros(len(xyz[f]), dtype=bool)
        if len(mine):
            d, _ = cKDTree(xyz[f][exists]).query(mine)
            ghosts += int((d > 10).sum())
            errors += d[d <= 10].tolist()
            near[exists] = cKDTree(mine).query(xyz[f][exists])[0] <= 10
        for key, want in (("seen", vis[f] >= 3), ("alone", alone[f] >= 3)):
            hits[key][0] += int((near & want).sum())
            hits[key][1] += int(want.sum())
    fig.walk_recall = hits["seen"][0] / max(hits["seen"][1], 1)
    fig.walk_recall_isolated = hits["alone"][0] / max(hits["alone"][1], 1)
    fig.walk_ghosts = ghosts / max(len(points), 1)
    fig.walk_rmse_mm = float(np.sqrt(np.mean(np.square(errors)))) if errors else float("nan")
    fig.walk_reproj_px = float(np.median(points.rms_px)) if len(points) else float("nan")


def _stick_error(plan: SynthPlan, table: tuple, L: NDArray, n: int) -> float:
    """Mean absolute error (mm) of the stick length over fields with both ends found."""
    points = reconstruct_trial(*table, L, RECON)
    xyz, _ = _seen(plan, "stick", n)
    errors = []
    for f in range(len(xyz)):
        mine = points.xyz_mm[points.field == f]
        if len(mine) < 2:
            continue
        d, j = cKDTree(mine).query(xyz[f])
        if np.all(d <= 10) and j[0] != j[1]:
            errors.append(abs(np.linalg.norm(mine[j[0]] - mine[j[1]]) - STICK_LENGTH_MM))
    return float(np.mean(errors)) if errors else float("nan")
