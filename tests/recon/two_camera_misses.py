"""Where reconstruction misses markers seen by exactly two cameras (issue 27; not a test).

    python -m tests.recon.two_camera_misses [seed ...] [--rig=lowcost|kiss3|modern3]

The trials of :mod:`tests.tracking.few_cameras_acceptance` (same scenario, same seeds),
reconstructed with default settings; every (field, marker) that exactly two cameras see
and no point finds within 10 mm is put in one category:

* ``merged``: in one of the two cameras the marker's image merged with another marker's
  (one blob for both, the other marker's), so it has one blob of its own;
* ``taken``: both blobs exist, one or both used by other points;
* ``band``: both free, outside each other's epipolar band;
* ``rejected``: both free and in band, the pair refused (residual limit, continuity or a
  contest it lost).

For the merged ones it also prints how long the merge lasts (fields from the last field
the marker was found to the next one, median and 90th percentile) and how far the point
of the marker's own blob and the merged blob lies from the truth (median, and how many
within the 10 mm the recall counts): what reusing the merged blob could give.
"""

from __future__ import annotations

import sys

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import project
from kisscal.dlt.triangulate import triangulate_observations
from kisscal.recon import ReconParams, reconstruct_trial
from kisscal.recon.epipolar import all_fundamentals, pair_distances_px
from tests.recon.scenario import Table2D, observe
from tests.recon.subsets import found_and_ghosts
from tests.tracking.few_cameras_acceptance import FIELDS, dropouts

RIGS = {"lowcost": ("lowcost", None), "kiss3": ("kiss", 3), "modern3": ("modern", 3)}


def _trial(preset: str, seed: int, n_cameras: int | None) -> tuple:
    from kisscal.synth.plan import plan_session
    from kisscal.synth.presets import synth_options
    from kisscal.synth.scene import visibility

    plan = plan_session(synth_options(preset, seed, fields=FIELDS[preset], n_cameras=n_cameras))
    rig, motion = plan.rig, plan.trials["walk01"]
    visible = np.stack([visibility(cam, motion) for cam in rig], axis=-1)
    visible &= ~dropouts(visible.shape, motion.rate_hz, seed)
    dlts = np.array([cam.dlt for cam in rig])
    tab = observe(dlts, rig[0].size_px, motion.xyz_mm, visible, seed)
    return tab, dlts, motion.xyz_mm, visible, motion.rate_hz


def _merge_span(found: NDArray[np.bool_], f: int, m: int) -> int:
    """Fields between the last field before ``f`` and the first after it where marker
    ``m`` is found (to the trial's ends when never)."""
    before = np.flatnonzero(found[:f, m])
    after = np.flatnonzero(found[f + 1 :, m])
    lo = before[-1] if len(before) else -1
    hi = f + 1 + after[0] if len(after) else len(found)
    return int(hi - lo - 1)


def misses(preset: str, seed: int, n_cameras: int | None) -> str:
    """One line of counts per category for a trial (see module)."""
    tab, dlts, xyz, visible, rate = _trial(preset, seed, n_cameras)
    pts = reconstruct_trial(tab.field, tab.camera, tab.uv, dlts, ReconParams(), rate)
    found, ghosts = found_and_ghosts(pts.field, pts.xyz_mm, xyz)
    exactly2 = visible.sum(axis=2) == 2
    row = np.full(visible.shape, -1)
    t = tab.truth >= 0
    row[tab.field[t], tab.truth[t], tab.camera[t]] = np.flatnonzero(t)
    F = all_fundamentals(dlts)
    count = dict.fromkeys(("merged", "taken", "band", "rejected"), 0)
    span, err = [], []
    for f, m in zip(*np.nonzero(exactly2 & ~found), strict=True):
        cams = np.flatnonzero(visible[f, m])
        r = row[f, m, cams]
        if (r < 0).any():
            count["merged"] += 1
            span.append(_merge_span(found, f, m))
            if (r >= 0).sum() == 1:
                err.append(_reuse_error(tab, dlts, xyz, f, m, cams, r))
        elif (pts.marker[r] >= 0).any():
            count["taken"] += 1
        else:
            d = pair_distances_px(F[cams[0], cams[1]], tab.uv[r[:1]], tab.uv[r[1:]])
            count["band" if np.ravel(d)[0] > ReconParams().epipolar_band_px else "rejected"] += 1
    line = (
        f"{preset} {n_cameras or 'all'} seed {seed}: recall2 {100 * found[exactly2].mean():.2f} %"
        f" ({int((exactly2 & ~found).sum())} missed of {int(exactly2.sum())}), ghosts"
        f" {100 * ghosts / max(len(pts), 1):.2f} %; "
        + ", ".join(f"{k} {v}" for k, v in count.items())
    )
    if span:
        e = np.asarray(err)
        line += (
            f"; merges last {np.median(span):.0f} / {np.percentile(span, 90):.0f} fields"
            f" (median / p90); reusing the merged blob: {np.median(e):.1f} mm median,"
            f" {int((e < 10).sum())}/{len(e)} within 10 mm"
        )
    return line


def _reuse_error(
    tab: Table2D,
    dlts: NDArray[np.float64],
    xyz: NDArray[np.float64],
    f: int,
    m: int,
    cams: NDArray[np.int64],
    r: NDArray[np.int64],
) -> float:
    """3D error (mm) of the marker's own blob triangulated with the blob of the other
    camera nearest to the marker's image there (the blob it merged into)."""
    own, lost = r[r >= 0][0], cams[r < 0][0]
    rows = np.flatnonzero((tab.field == f) & (tab.camera == lost))
    at = project(dlts[lost], xyz[f, m][None])[0]
    merged = rows[np.argmin(np.linalg.norm(tab.uv[rows] - at, axis=1))]
    pair = np.array([own, merged])
    tri = triangulate_observations(dlts, np.zeros(2, dtype=int), tab.camera[pair], tab.uv[pair], 1)
    return float(np.linalg.norm(tri.xyz_mm[0] - xyz[f, m]))


if __name__ == "__main__":
    seeds = tuple(int(a) for a in sys.argv[1:] if not a.startswith("--")) or (301, 302, 303)
    only = next((a.split("=", 1)[1] for a in sys.argv if a.startswith("--rig=")), None)
    for name, (preset, n_cams) in RIGS.items():
        if only is None or name == only:
            for seed in seeds:
                print(misses(preset, seed, n_cams), flush=True)
