"""Issue 17's "done when" numbers for gait events and spatiotemporal parameters (run it):

    python -m tests.gait.acceptance          # 24 synthetic trials per rate, walking5.c3d
    python -m tests.gait.acceptance 48       # more trials

Synthetic: the grounded walker (true foot contacts), headings spread over 360 degrees,
statures 1.5-1.9 m, 0.7-1.4 m/s, 5 s, 0.5 mm noise per coordinate, at 100 and 50 Hz.
Real: walking5.c3d (Vicon, 250 Hz, its own labelled markers), its force plates' contacts
(20 N) as truth where the foot is on the plate; also resampled to 125 and 50 Hz.
"""

from __future__ import annotations

import sys

import numpy as np

from kisscal.gait import detect_events, progression, spatiotemporal_parameters
from kisscal.gait.events import _coarse
from kisscal.gait.params import DEFAULT_PARAMS
from kisscal.gait.signals import derivative
from kisscal.gait.table import EVENTS, SIDES
from tests.gait import _synth, _walking5

RELATIVE = ("cadence", "walking_speed", "stride_time", "stride_length", "step_length", "step_width")
POINTS = ("stance", "swing", "double_support")


def _published(markers, rate: float) -> dict[str, dict[str, np.ndarray]]:
    """Events by the published criteria alone, for comparison: Zeni et al. 2008's
    crossings (foot strike, foot off) and O'Connor et al. 2007's peak of the foot
    centre's upward velocity (foot off)."""
    direction, pelvis_v = progression(markers)
    speed = np.linalg.norm(pelvis_v[:, :2], axis=1)
    t = markers.time_s
    out: dict[str, dict[str, np.ndarray]] = {}
    for side in SIDES:
        strikes, offs = _coarse(markers, side, direction, pelvis_v, speed, DEFAULT_PARAMS)
        lift = derivative((markers.heel[side][:, 2] + markers.toe[side][:, 2]) / 2, rate, 40.0)
        fva = []
        for c in offs / rate:
            sel = np.flatnonzero(np.abs(t - (c - 0.03)) < 0.08)
            if len(sel) and np.all(np.isfinite(lift[sel])):
                fva.append(t[sel[np.argmax(lift[sel])]])
        out[side] = {"zeni_fs": strikes / rate, "zeni_fo": offs / rate, "oconnor_fo": np.array(fva)}
    return out


def _nearest(found: np.ndarray, t: float) -> float:
    return float(found[np.argmin(np.abs(found - t))] - t) if len(found) else float("nan")


def synthetic(n_trials: int) -> list[str]:
    lines = [
        "Events on synthetic trials (errors against the walker's true contacts)",
        f"{'rate':>6} {'event':<12} {'n':>4} {'MAE ms':>7} {'max ms':>7} {'missed':>6}"
        f" {'extra':>6}",
    ]
    st_lines = [
        "Spatiotemporal error, per trial and side (lengths/times: % of truth; phases: % points)",
        f"{'rate':>6} {'parameter':<15} {'mean':>7} {'max |e|':>8} {'n':>4}",
    ]
    cmp = {k: [] for k in ("zeni_fs", "ours_fs", "zeni_fo", "oconnor_fo", "ours_fo")}
    for rate in (100.0, 50.0):
        errors = {e: [] for e in EVENTS}
        missed = dict.fromkeys(EVENTS, 0)
        extra = dict.fromkeys(EVENTS, 0)
        st = {p: [] for p in RELATIVE + POINTS}
        for k, (heading, height, speed) in enumerate(_synth.grid(n_trials)):
            tr = _synth.trial(k, rate, heading, height, speed)
            sc = _synth.score(tr.events, tr.truth, (tr.motion.n_fields - 1) / rate)
            for e in EVENTS:
                errors[e] += sc.errors_s[e]
                missed[e] += sc.missed[e]
                extra[e] += sc.extra[e]
            true = _synth.true_spatiotemporal(tr)
            found = _synth.measured_spatiotemporal(tr)
            for p in st:
                for side in SIDES:
                    a, b = true.mean(p, side), found.mean(p, side)
                    st[p].append(100 * (b - a) / a if p in RELATIVE else b - a)
            if rate == 100.0:
                _compare(cmp, _published(tr.markers, rate), tr.events, tr.truth.events)
        for e in EVENTS:
            err = np.abs(errors[e]) * 1000
            lines.append(
                f"{rate:6.0f} {e:<12} {len(err):4d} {err.mean():7.2f} {err.max():7.2f}"
                f" {missed[e]:6d} {extra[e]:6d}"
            )
        for p, v in st.items():
            v = np.asarray(v)
            st_lines.append(
                f"{rate:6.0f} {p:<15} {np.nanmean(v):7.2f} {np.nanmax(np.abs(v)):8.2f} {len(v):4d}"
            )
    lines += [""] + st_lines + ["", "Published criteria alone, 100 Hz (mean and MAE ms):"]
    for k, v in cmp.items():
        v = np.asarray(v) * 1000
        lines.append(f"  {k:<11} mean {np.nanmean(v):7.1f}  MAE {np.nanmean(np.abs(v)):6.1f}")
    return lines


def _compare(cmp: dict, published: dict, ours, truth) -> None:
    for side in SIDES:
        for t in truth.times(side, "foot_strike"):
            cmp["zeni_fs"].append(_nearest(published[side]["zeni_fs"], t))
            cmp["ours_fs"].append(_nearest(ours.times(side, "foot_strike"), t))
        for t in truth.times(side, "foot_off"):
            cmp["zeni_fo"].append(_nearest(published[side]["zeni_fo"], t))
            cmp["oconnor_fo"].append(_nearest(published[side]["oconnor_fo"], t))
            cmp["ours_fo"].append(_nearest(ours.times(side, "foot_off"), t))
    for k in cmp:  # events at the trial ends have no match: drop them
        cmp[k] = [x for x in cmp[k] if np.isfinite(x) and abs(x) < 0.15]


def walking5() -> list[str]:
    plates = _walking5.plate_events()
    lines = ["walking5.c3d events (own markers; FP = force plate contact, 20 N)"]
    gm, rate = _walking5.load()
    found = detect_events(gm)
    lines.append(f"{'side':<6} {'event':<12} {'field':>5} {'time_s':>8}  force plate")
    for row in found.rows():
        near = [p for p in plates if p.side == row["side"] and p.event == row["event"]]
        near = [p for p in near if abs(p.time_s - row["time_s"]) < 0.1]
        fp = ""
        if near:
            error_ms = 1000 * (row["time_s"] - near[0].time_s)
            fp = f"plate {near[0].plate}: {near[0].time_s:.4f} s, error {error_ms:+.1f} ms"
        lines.append(
            f"{row['side']:<6} {row['event']:<12} {row['field']:5d} {row['time_s']:8.4f}  {fp}"
        )
    lines.append("Errors against the force plates when resampled (ms):")
    for step in (1, 2, 5):
        errs = []
        for offset in range(step):
            gm_s, _ = _walking5.load(step=step, offset=offset)
            ev = detect_events(gm_s)
            errs.append(
                [
                    1000 * (_nearest(ev.times(p.side, p.event), p.time_s - offset / rate))
                    for p in plates
                ]
            )
        errs = np.asarray(errs)
        cells = ", ".join(
            f"{p.side} {p.event} {np.abs(errs[:, i]).mean():.1f}" for i, p in enumerate(plates)
        )
        lines.append(f"  {rate / step:5.0f} Hz (mean |error| over {step} phase(s)): {cells}")
    pub = _published(gm, rate)
    lines.append("Published criteria alone at 250 Hz (ms against the plates):")
    for p in plates:
        keys = ("zeni_fs",) if p.event == "foot_strike" else ("zeni_fo", "oconnor_fo")
        cells = ", ".join(f"{k} {1000 * _nearest(pub[p.side][k], p.time_s):+.1f}" for k in keys)
        lines.append(f"  {p.side} {p.event}: {cells}")
    lines.append("walking5.c3d spatiotemporal parameters")
    lines.append(f"{'parameter':<15} {'side':<6} {'mean':>8} {'sd':>7} {'unit':<10} {'n':>2}")
    for r in spatiotemporal_parameters(found, gm).rows():
        lines.append(
            f"{r['parameter']:<15} {r['side']:<6} {r['mean']:8.3f} {r['sd']:7.3f}"
            f" {r['unit']:<10} {r['n_strides']:2d}"
        )
    return lines


def main(argv: list[str]) -> None:
    n = int(argv[1]) if len(argv) > 1 else 24
    print("\n".join(synthetic(n) + [""] + walking5()))


if __name__ == "__main__":
    main(sys.argv)
