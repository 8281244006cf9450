"""End to end on a synthetic session's truth files (the formats ``kisscal synth`` writes).

The 2D table is the rendered trial's true centroids (``u_ideal_px, v_ideal_px``: what
detection + linearisation should deliver) plus 0.05 px noise and the LEDs of
``truth/leds``; overlapping spots (``isolated == 0``) are merged into one blob at their mean,
as a detector without a split test would report them.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from kisscal.recon import ReconParams, reconstruct_trial

from .scenario import score


def _read_csv(path: Path) -> dict[str, list[str]]:
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    return {k: [r[k] for r in rows] for k in rows[0]}


def _load(session: Path, trial: str, merge: bool, seed: int = 0):
    cams = json.loads((session / "truth" / "cameras.json").read_text())["cameras"]
    ids = [c["id"] for c in cams]
    dlts = np.array([c["dlt"] for c in cams], dtype=float)
    m = _read_csv(session / "truth" / "trials" / trial / "markers.csv")
    names = sorted(set(m["marker"]), key=m["marker"].index)
    n_fields = max(int(f) for f in m["field"]) + 1
    xyz = np.full((n_fields, len(names), 3), np.nan)
    visible = np.zeros((n_fields, len(names), len(ids)), dtype=bool)
    for k in range(len(m["field"])):
        f, j = int(m["field"][k]), names.index(m["marker"][k])
        xyz[f, j] = [float(m[a][k]) for a in ("x_mm", "y_mm", "z_mm")]
        visible[f, j] = [m[f"visible_{c}"][k] == "1" for c in ids]
    c = _read_csv(session / "truth" / "trials" / trial / "centroids.csv")
    field = np.array(c["field"], dtype=int)
    camera = np.array([ids.index(x) for x in c["camera"]])
    uv = np.column_stack([np.array(c["u_ideal_px"], float), np.array(c["v_ideal_px"], float)])
    truth = np.array([names.index(x) for x in c["marker"]])
    isolated = np.array(c["isolated"], dtype=int) == 1
    if merge:
        # overlapping spots of one field and camera become one blob at their mean
        keep = isolated.copy()
        extra_f, extra_c, extra_uv = [], [], []
        for f, cam in set(zip(field[~isolated], camera[~isolated], strict=True)):
            rows = np.flatnonzero((field == f) & (camera == cam) & ~isolated)
            extra_f.append(f)
            extra_c.append(cam)
            extra_uv.append(uv[rows].mean(axis=0))
        field = np.r_[field[keep], extra_f]
        camera = np.r_[camera[keep], extra_c]
        uv = np.vstack([uv[keep], np.reshape(extra_uv, (-1, 2))])
        truth = np.r_[truth[keep], np.full(len(extra_f), -1)]
    rng = np.random.default_rng(seed)
    uv = uv + rng.normal(0, 0.05, uv.shape)
    for k, cam_id in enumerate(ids):
        leds = session / "truth" / "leds" / f"{cam_id}.csv"
        if not leds.is_file() or leds.stat().st_size < 20:
            continue
        led = _read_csv(leds)
        for u, v in zip(led["u_px"], led["v_px"], strict=True):
            # LED spots are stationary; their centres are ideal-ish within the jitter
            field = np.r_[field, np.arange(n_fields)]
            camera = np.r_[camera, np.full(n_fields, k)]
            uv = np.vstack([uv, [float(u), float(v)] + rng.normal(0, 0.1, (n_fields, 2))])
            truth = np.r_[truth, np.full(n_fields, -1)]
    return dlts, xyz, visible, field, camera, uv, truth


@pytest.mark.slow
@pytest.mark.parametrize("merge", [False, True])
def test_walk_trial_from_truth_files(small_session: Path, merge: bool) -> None:
    dlts, xyz, visible, field, camera, uv, truth = _load(small_session, "walk01", merge)
    pts = reconstruct_trial(field, camera, uv, dlts, ReconParams())
    if merge:
        # markers still seen as their own blob by >= 3 cameras must be found
        own = np.zeros_like(visible)
        real = truth >= 0
        own[field[real], truth[real], camera[real]] = True
        visible = own
    s = score(pts, xyz, visible)
    assert s.recall >= 0.995, s
    assert s.ghost_fraction <= 0.005, s
    assert s.rmse_mm <= 1.0, s
