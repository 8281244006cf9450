"""Issue 17's "done when" numbers for labelling from a shipped marker set (run it):

    python -m tests.tracking.markerset_acceptance synthetic [n]   # (a) set only, n trials
    python -m tests.tracking.markerset_acceptance walking5         # (b) full body, set only
    python -m tests.tracking.markerset_acceptance mirror [every]   # (c) walking frames as templates

(a) The grounded walker (kisscal.synth.walker), 4 s, statures 1.5-1.9 m, headings spread
over 360 degrees, 0.7-1.4 m/s, at 100 and 50 Hz; its 15 markers (Plug-in Gait lower body
with SACR for LPSI/RPSI) as reconstruction would deliver them: 0.5 mm noise per
coordinate, 1 % of the fields start a dropout of 1-4 fields, about one ghost point per
field living 1-4 fields. Labelled with ``marker_set=plug-in-gait-lower`` only (no
template, no stature).
(b) walking5.c3d's 34 physical markers (joint centres, names ending JC, dropped), every
field's points in random order with no names, tracked and labelled with
``plug-in-gait-full`` only (39 names; 16 of them are on walking5's subject, through the
set's aliases, the 18 other markers are not in the set).
(c) walking5.c3d's physical markers, anonymous, labelled with the template taken from
every ``every``-th frame in which all 34 are seen (names = walking5's own): each result is
right, or its wrong labels are flagged, or a silent swap (the count must be 0).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from kisscal.io.c3d import read_c3d_points
from kisscal.markersets import marker_set
from kisscal.tracking import TrackingParams, build_trajectories
from tests.gait._synth import grid, walker
from tests.gait._walking5 import path as walking5_path
from tests.tracking._data import observe
from tests.tracking._eval import score

LOWER = (
    "LASI", "RASI", "SACR", "LTHI", "LKNE", "LTIB", "LANK", "LHEE", "LTOE",
    "RTHI", "RKNE", "RTIB", "RANK", "RHEE", "RTOE",
)  # fmt: skip


def walker_trial(seed: int, height_m: float, heading_deg: float, speed_m_s: float, rate_hz: float):
    """True positions (15, F, 3) of a 4 s grounded walk and its anonymous observed points."""
    m = walker(seed, rate_hz, heading_deg, height_m, speed_m_s, duration_s=4.0)
    truth = m.xyz_mm.transpose(1, 0, 2)[[m.names.index(x) for x in LOWER]]
    field, xyz, _, visible = observe(truth, seed, noise_mm=0.5, volume_x=None)
    return truth, visible, field, xyz


def owners(result, truth_pos: np.ndarray, true_names) -> list[str]:
    """The true marker of each output trajectory (majority of its measured samples)."""
    tr = result.tracks
    out = []
    for t in range(tr.n_tracks):
        rows = (tr.track == t) & (tr.status == 0)
        d = np.linalg.norm(truth_pos[:, tr.field[rows]] - tr.xyz_mm[rows][None], axis=2)
        nearest = np.nanargmin(np.where(np.isfinite(d), d, np.inf), axis=0)
        out.append(true_names[int(np.bincount(nearest, minlength=len(true_names)).argmax())])
    return out


def wrong_labels(result, truth_pos: np.ndarray, true_names) -> list[tuple[str, str]]:
    """(label, true marker) of every named trajectory whose true marker differs."""
    unnamed = set(result.labelling.unlabelled)
    return [
        (label, own)
        for t, (label, own) in enumerate(
            zip(result.labels, owners(result, truth_pos, true_names), strict=True)
        )
        if t not in unnamed and own != label
    ]


def synthetic(n_trials: int) -> list[str]:
    pig = marker_set("plug-in-gait-lower", names=LOWER)
    lines = [
        "(a) set only (plug-in-gait-lower, SACR variant) on the grounded walker",
        f"{'rate':>5} {'seed':>4} {'heading':>7} {'H m':>5} {'H est':>5} {'m/s':>4} "
        f"{'right':>6} {'switch':>6} {'unnamed':>7} {'flagged':>7} {'silent':>6} {'conf':>5} "
        f"{'s':>5}",
    ]
    total = {"trials": 0, "all_right": 0, "switches": 0, "silent": 0}
    for rate in (100.0, 50.0):
        for seed, (heading, height, speed) in enumerate(grid(n_trials, int(rate))):
            truth, visible, field, xyz = walker_trial(seed, height, heading, speed, rate)
            t0 = time.perf_counter()
            res = build_trajectories(field, xyz, TrackingParams(), marker_set=pig, rate_hz=rate)
            dt = time.perf_counter() - t0
            s = score(res, truth, visible, LOWER)
            lab = res.labelling
            wrong = wrong_labels(res, truth, LOWER)
            silent = [w for w in wrong if w[0] not in lab.flagged]
            named = s.n_tracks - len(lab.unlabelled)
            conf = min(lab.confidence.values()) if lab.confidence else float("nan")
            total["trials"] += 1
            total["all_right"] += s.labels_correct == 15 and named == 15
            total["switches"] += s.identity_switches
            total["silent"] += len(silent)
            lines.append(
                f"{rate:5.0f} {seed:4d} {heading:7.1f} {height:5.2f} {lab.height_mm / 1000:5.2f} "
                f"{speed:4.2f} {s.labels_correct:3d}/{named:<2d} {s.identity_switches:6d} "
                f"{len(lab.unlabelled):7d} {len(lab.flagged):7d} {len(silent):6d} {conf:5.2f} "
                f"{dt:5.1f}"
            )
    lines.append(
        f"trials {total['trials']}: 15/15 right in {total['all_right']}, identity switches "
        f"{total['switches']}, silently wrong labels {total['silent']}"
    )
    return lines


def _walking5(step: int = 1):
    labels, xyz, rate = read_c3d_points(walking5_path())
    keep = [i for i, n in enumerate(labels) if not n.upper().endswith("JC")]
    labels = tuple(labels[i] for i in keep)
    xyz = xyz[::step, keep]
    rng = np.random.default_rng(0)
    f_idx, m_idx = np.nonzero(np.isfinite(xyz[..., 0]))
    order = rng.permutation(f_idx.size)  # every field's points in random order
    return labels, xyz, rate / step, f_idx[order], xyz[f_idx[order], m_idx[order]]


def walking5_full() -> list[str]:
    labels, xyz, rate, field, points = _walking5()
    full = marker_set("plug-in-gait-full")
    t0 = time.perf_counter()
    res = build_trajectories(field, points, TrackingParams(), marker_set=full, rate_hz=rate)
    dt = time.perf_counter() - t0
    lab = res.labelling
    truth = xyz.transpose(1, 0, 2)
    expected = {n: full.aliases.get(n, n) for n in labels}
    in_set = sorted(n for n in labels if expected[n] in full.names)
    lines = [
        "(b) walking5.c3d, anonymous, set only (plug-in-gait-full)",
        f"stature estimated {lab.height_mm:.0f} mm; fits the set: {lab.fits_marker_set}; "
        f"{len(res.labels)} trajectories; {dt:.1f} s",
        f"{'marker':>7} {'set name':>8} {'labelled':>8} {'result':>8}",
    ]
    got: dict[str, str] = {}
    for label, own in zip(res.labels, owners(res, truth, labels), strict=True):
        got.setdefault(own, label)
    counts = {"right": 0, "flagged": 0, "silent": 0}
    for name in in_set:
        label = got.get(name, "-")
        if label == expected[name]:
            kind = "right"
        elif label in lab.flagged or label == "-" or label.startswith("M"):
            kind = "flagged"
        else:
            kind = "silent"
        counts[kind] += 1
        lines.append(f"{name:>7} {expected[name]:>8} {label:>8} {kind:>8}")
    others = [n for n in labels if n not in in_set]
    taken = [f"{n}->{got.get(n, '-')}" for n in others]
    silent_other = [x for x in taken if not x.endswith("-") and x.split("->")[1] not in lab.flagged]
    lines.append(f"markers of the set: {counts}")
    lines.append(f"markers not in the set (name given): {', '.join(taken)}")
    lines.append(f"... of which unflagged: {', '.join(silent_other) or 'none'}")
    return lines


def mirror(every: int) -> list[str]:
    labels, xyz, rate, field, points = _walking5()
    complete = np.flatnonzero(np.isfinite(xyz[..., 0]).all(axis=1))[::every]
    truth = xyz.transpose(1, 0, 2)
    counts = {"right": 0, "flagged": 0, "silent": 0}
    lines = [
        f"(c) mirror test: walking5.c3d anonymous, template = each {every}th complete frame",
        f"{'frame':>5} {'result':>8} {'wrong':>5} {'flagged':>7} {'exchanged':>9} {'mirror':>6}",
    ]
    for frame in complete:
        res = build_trajectories(field, points, TrackingParams(), labels, xyz[frame], rate_hz=rate)
        lab = res.labelling
        wrong = wrong_labels(res, truth, labels)
        silent = [w for w in wrong if w[0] not in lab.flagged]
        kind = "right" if not wrong else ("flagged" if not silent else "silent")
        counts[kind] += 1
        lines.append(
            f"{frame + 1:5d} {kind:>8} {len(wrong):5d} {len(lab.flagged):7d} "
            f"{len(lab.exchanged):9d} {lab.mirror_fit_ratio:6.2f}"
        )
    lines.append(f"templates {len(complete)}: {counts}")
    return lines


if __name__ == "__main__":
    what = sys.argv[1] if len(sys.argv) > 1 else "synthetic"
    arg = int(sys.argv[2]) if len(sys.argv) > 2 else None
    if what == "synthetic":
        out = synthetic(arg or 16)
    elif what == "walking5":
        out = walking5_full()
    else:
        out = mirror(arg or 1)
    print("\n".join(out))
