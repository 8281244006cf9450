"""Why reconstruction misses markers seen by exactly two cameras (issue 27; not a test).

    python -m tests.recon.two_camera_why 303 [--rig=lowcost|kiss3] [--hidden] [-v]

The trials of :mod:`tests.tracking.few_cameras_acceptance` exactly (centroid merges, the
marker set's rigid triangles, ``--hidden`` as there), with the two-camera step traced:
every (field, marker) that exactly two cameras see and no point finds within 10 mm is
put in one class:

* ``merged``: in one of the two views its image merged with another marker's;
* ``taken by <who>``: both blobs exist, one used by a point of another true marker
  (``other``, with its number of cameras) or by a ghost (``ghost``);
* ``band``: both free, outside each other's epipolar band;
* ``residual``: in band, the pair beyond the residual limit (or at a camera, or LEDs);
* ``no trajectory``: no four-field window within the continuity tolerance, no body fit
  (``-v`` prints the score, the pair's error, its body fit and the marker's cameras and
  finds over f-3..f+3);
* ``contested``: continues a trajectory but lost (or never won) the competition;
* ``claimed``: won, then withdrawn as a piece whose rays other trajectories claim;
* ``later``: won in the two-camera step, lost after it (grouping, residual split);

Stop 40, ``--hidden`` (missed: merged / taken by another marker's 2-camera point / taken
by a 3-camera point / taken by a ghost / no trajectory / residual): lowcost 301 28 =
10/0/1/1/11/5, 302 37 = 12/0/1/0/22/2, 303 50 = 17/11/4/7/8/3, 311 34 =
19/1/2/3/7/2, 312 38 = 20/0/6/5/4/3, 313 0; kiss 3 301 21 = 5/0/3/0/9/4, 302 32 =
5/0/3/9/9/6. 303's eleven "taken by a 2-camera point" are one merge: marker 13 (cameras
1, 3) holds the blob it shares with marker 12 (cameras 2, 3) in camera 3
(``ReconParams.deblend_held``, on by default, recovers it: 303 40 = 16/3/4/6/8/3, 312 30
= 12/0/6/5/4/3). The "no trajectory" ones (302: 22) are two-camera glimpses of one to
three fields, or noisy pairs, where the walk enters and leaves the volume: no known point
of the marker within three fields and fewer than two of its segment's markers known.
"""

from __future__ import annotations

import sys
from collections import Counter

import numpy as np

import kisscal.recon.pairs as pairs_mod
from kisscal.dlt.triangulate import triangulate_observations as tri
from kisscal.recon import ReconParams, reconstruct_trial
from kisscal.recon.body import RigidTriangles, body_error
from kisscal.recon.epipolar import all_fundamentals, pair_distances_px
from tests.recon.scenario import observe
from tests.recon.subsets import found_and_ghosts
from tests.tracking.few_cameras_acceptance import FIELDS, dropouts

TRACE: dict[str, list] = {"choose": [], "body": [], "on": []}


def _traced(name, fn):
    def wrapper(*args, **kw):
        out = fn(*args, **kw)
        if TRACE["on"]:
            TRACE[name].append((args, out))
        return out

    return wrapper


def _install() -> None:
    import kisscal.recon.match as match_mod

    pairs_mod.choose_pairs = _traced("choose", pairs_mod.choose_pairs)
    pairs_mod.body_pairs = _traced("body", pairs_mod.body_pairs)
    two = match_mod.match_two_camera

    def in_two(*args, **kw):
        TRACE["on"].append(1)
        TRACE["input"] = args
        try:
            out = two(*args, **kw)
            TRACE["limit"] = out[1]
            return out
        finally:
            TRACE["on"].pop()

    match_mod.match_two_camera = in_two


def _setup(preset: str, seed: int, n_cameras: int | None, hidden: bool):
    from kisscal.synth.plan import plan_session
    from kisscal.synth.presets import synth_options
    from kisscal.synth.scene import visibility

    plan = plan_session(synth_options(preset, seed, fields=FIELDS[preset], n_cameras=n_cameras))
    rig, motion = plan.rig, plan.trials["walk01"]
    visible = np.stack([visibility(c, motion) for c in rig], axis=-1)
    visible &= ~dropouts(visible.shape, motion.rate_hz, seed)
    dlts = np.array([c.dlt for c in rig])
    tab = observe(dlts, rig[0].size_px, motion.xyz_mm, visible, seed, merge="centroid")
    body = RigidTriangles.from_marker_set(plan.marker_names, plan.template_mm, plan.segments)
    params = ReconParams(deblend_hidden=hidden)
    return tab, dlts, motion, visible, body, params


def _pair_index(a, b, r0, r1):
    hit = np.flatnonzero(((a == r0) & (b == r1)) | ((a == r1) & (b == r0)))
    return int(hit[0]) if len(hit) else -1


def why(preset: str, seed: int, n_cameras: int | None, hidden: bool, verbose: bool) -> str:
    for k in ("choose", "body"):
        TRACE[k].clear()
    tab, dlts, motion, visible, body, params = _setup(preset, seed, n_cameras, hidden)
    xyz = motion.xyz_mm
    pts = reconstruct_trial(tab.field, tab.camera, tab.uv, dlts, params, motion.rate_hz, body)
    found, ghosts = found_and_ghosts(pts.field, pts.xyz_mm, xyz)
    exactly2 = visible.sum(axis=2) == 2
    row = np.full(visible.shape, -1)
    t = tab.truth >= 0
    row[tab.field[t], tab.truth[t], tab.camera[t]] = np.flatnonzero(t)
    # the marker each point is (nearest truth within 10 mm), -1 for a ghost
    d = np.linalg.norm(pts.xyz_mm[:, None] - xyz[pts.field], axis=2)
    d = np.where(np.isfinite(d), d, np.inf)
    who = np.where(d.min(axis=1) < 10.0, d.argmin(axis=1), -1)
    F = all_fundamentals(dlts)
    # the two-camera step's first choose_pairs call holds all its candidates
    last_body_args, body_won = TRACE["body"][-1]
    a_f, b_f = last_body_args[0][:2]
    first = TRACE["choose"][0][0]
    a0, b0, xyz0, field0 = first[:4]
    won0 = TRACE["choose"][0][1]
    ever_won = set()
    for args, out in TRACE["choose"]:
        for x, y in zip(args[0][out], args[1][out], strict=True):
            ever_won.add((min(x, y), max(x, y)))
    pool = np.concatenate([first[4], xyz0]), np.concatenate([first[5], field0])
    score = pairs_mod.continuity_mm(
        xyz0, field0, *pool, params.two_camera_step_mm, params.two_camera_continuity_mm
    )
    count: Counter = Counter()
    lines = []
    for f, m in zip(*np.nonzero(exactly2 & ~found), strict=True):
        cams = np.flatnonzero(visible[f, m])
        r = row[f, m, cams]
        extra = ""
        if (r < 0).any():
            c = "merged"
        elif (pts.marker[r] >= 0).any():
            taker = pts.marker[r][pts.marker[r] >= 0][0]
            k = who[taker]
            c = "taken by ghost" if k < 0 else f"taken by other ({pts.n_cameras[taker]} cams)"
            br = pts.blob_row[taker][pts.blob_row[taker] >= 0]
            extra = f" taker {k}, blobs of {tab.truth[br].tolist()} in {tab.camera[br].tolist()}"
        else:
            keep = np.flatnonzero(~pts.stationary)
            rk = np.searchsorted(keep, r)
            dist = pair_distances_px(F[cams[0], cams[1]], tab.uv[r[:1]], tab.uv[r[1:]])
            i0 = _pair_index(a0, b0, rk[0], rk[1])
            i_f = _pair_index(a_f, b_f, rk[0], rk[1])
            key = (min(rk), max(rk))
            if np.ravel(dist)[0] > params.epipolar_band_px:
                c = "band"
            elif i0 < 0:
                c = "residual"
                m_in = TRACE["input"][0]
                tt = tri(dlts, np.zeros(2, dtype=int), tab.camera[r], tab.uv[r], 1, 2)
                extra = (
                    f" rms {tt.rms_px[0]:.3f} limit {TRACE['limit']:.3f}, marker at input "
                    f"{m_in[rk].tolist()}, err {np.linalg.norm(tt.xyz_mm[0] - xyz[f, m]):.1f} mm"
                )
            elif i_f >= 0 and body_won[i_f]:
                c = "later"
            elif key in ever_won:
                c = "claimed"
            else:
                c = "contested" if score[i0] <= params.two_camera_continuity_mm else "no trajectory"
                e = np.linalg.norm(xyz0[i0] - xyz[f, m])
                be = body_error(xyz0[i0 : i0 + 1], field0[i0 : i0 + 1], first[4], first[5], body)
                nb = [
                    int(visible[g, m].sum()) for g in range(max(f - 3, 0), min(f + 4, len(found)))
                ]
                fb = [int(found[g, m]) for g in range(max(f - 3, 0), min(f + 4, len(found)))]
                extra = (
                    f" score {score[i0]:.1f}, pair {e:.1f} mm off, body {be[0]:.1f}, "
                    f"cams f-3..f+3 {nb} found {fb}, won {won0[i0]}"
                )
        count[c] += 1
        lines.append(f"  field {f} marker {m} cams {cams.tolist()}: {c}{extra}")
    head = (
        f"{preset} {n_cameras or 'all'} seed {seed} hidden={hidden}: recall2 "
        f"{100 * found[exactly2].mean():.2f} % ({int((exactly2 & ~found).sum())} missed of "
        f"{int(exactly2.sum())}), ghosts {ghosts}/{len(pts)}; "
        + ", ".join(f"{k} {v}" for k, v in count.most_common())
    )
    return "\n".join([head, *lines]) if verbose else head


RIGS = {"lowcost": ("lowcost", None), "kiss3": ("kiss", 3), "modern3": ("modern", 3)}

if __name__ == "__main__":
    _install()
    seeds = tuple(int(a) for a in sys.argv[1:] if not a.startswith("-")) or (303,)
    only = next((a.split("=", 1)[1] for a in sys.argv if a.startswith("--rig=")), "lowcost")
    for seed in seeds:
        print(
            why(RIGS[only][0], seed, RIGS[only][1], "--hidden" in sys.argv, "-v" in sys.argv),
            flush=True,
        )
