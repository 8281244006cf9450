"""Pass / warn / fail of every check the report's status block shows, with its limit.

One :class:`Verdict` per camera, one for the calibration's 3D error, one per trial (for a
stick or thrown-marker trial, its validation result). Calibration figures over their
limits fail; a trial whose markers are not all there warns; a trial that failed fails.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kisscal.report.gather import SessionOutputs, TrialOutputs
from kisscal.report.markers import MarkerStats, SegmentStats, marker_stats, segment_stats
from kisscal.report.params import ReportParams
from kisscal.report.validation import (
    StickLength,
    ThrowFit,
    rate_doubt,
    stick_length,
    throw_fit,
)

PASS, WARN, FAIL, NONE = "pass", "warn", "fail", "none"
_ORDER = {NONE: 0, PASS: 1, WARN: 2, FAIL: 3}


@dataclass(frozen=True)
class Verdict:
    """One line of the status block: what was checked, the result, the limit, the state."""

    scope: str
    result: str
    limit: str
    state: str


def worst(states: list[str]) -> str:
    """The most serious of ``states`` (:data:`NONE` for none)."""
    return max(states, key=_ORDER.__getitem__, default=NONE)


def _within(value: float, limit: float) -> str:
    if not np.isfinite(value):
        return NONE
    return PASS if value <= limit else FAIL


def camera_verdicts(o: SessionOutputs) -> list[Verdict]:
    """Each camera's grid residual and DLT rms against their limits."""
    lim = o.limits
    out = []
    for cam in o.cameras:
        figures = o.camera_figures(cam)
        grid, dlt = figures.grid_rms_px, figures.dlt_rms_px
        parts = [
            f"grid residual {grid:.3f} px" if np.isfinite(grid) else "no grid linearisation",
            f"DLT rms {dlt:.3f} px" if np.isfinite(dlt) else "not calibrated",
        ]
        states = [_within(grid, lim.max_grid_px)]  # no grid: NONE, no verdict
        states.append(_within(dlt, lim.max_reproj_px) if np.isfinite(dlt) else FAIL)
        limit = f"grid ≤ {lim.max_grid_px:g} px, DLT ≤ {lim.max_reproj_px:g} px"
        out.append(Verdict(cam, "; ".join(parts), limit, worst(states)))
    return out


def rig_verdict(o: SessionOutputs) -> Verdict | None:
    """The calibration's 3D error on held-out rods (as ``kisscal check --max-3d-mm``)."""
    check = o.rig_check()
    limit = f"≤ {o.limits.max_3d_mm:g} mm"
    if math.isfinite(check.leave_one_rod_out_mean_mm):
        value = check.leave_one_rod_out_mean_mm
        text = (
            f"rods held out of the fit: mean {value:.2f} mm, "
            f"max {check.leave_one_rod_out_max_mm:.2f} mm"
        )
    elif math.isfinite(check.in_sample_mean_mm):
        value = check.in_sample_mean_mm
        text = f"rod markers in the fit: mean {value:.2f} mm (no rod held out)"
    else:
        return None
    return Verdict("3D error", text, f"mean {limit}", _within(value, o.limits.max_3d_mm))


@dataclass(frozen=True)
class TrialAnalysis:
    """What the report measured of one trial's trajectories (None where not applicable)."""

    name: str
    markers: list[MarkerStats]
    segments: list[SegmentStats]
    stick: StickLength | None
    throw: ThrowFit | None


def analyse_trial(o: SessionOutputs, t: TrialOutputs) -> TrialAnalysis:
    """Marker presence, segment lengths and the validation fits of one trial."""
    if t.dense is None:
        return TrialAnalysis(t.name, [], [], None, None)
    lim = o.limits
    labelled = o.trial_figures(t.name).fits_marker_set  # a gait trial: validation by name only
    stick = (
        stick_length(t.dense, t.name, o.rate_hz, lim.stick_length_mm, labelled)
        if lim.stick_length_mm is not None  # only a session that describes its stick
        else None
    )
    throw = None if stick else throw_fit(t.dense, t.name, o.rate_hz, lim.g_m_s2, labelled)
    return TrialAnalysis(
        t.name, marker_stats(t.dense), segment_stats(t.dense, o.segments), stick, throw
    )


def _validation_verdict(
    name: str, a: TrialAnalysis, lim: ReportParams, rate_hz: float
) -> Verdict | None:
    if a.stick is not None:
        s = a.stick
        err = s.mean_abs_error_mm
        state = PASS if max(err, s.sd_mm) <= lim.max_stick_error_mm else FAIL
        return Verdict(
            name,
            f"length {s.mean_mm:.2f} mm, SD {s.sd_mm:.2f} mm, mean |error| {err:.2f} mm "
            f"(true {s.true_mm:g} mm, {s.samples} fields)",
            f"|error| and SD ≤ {lim.max_stick_error_mm:g} mm",
            state,
        )
    if a.throw is not None:
        g = a.throw.g_m_s2
        rel = (g - lim.g_m_s2) / lim.g_m_s2
        doubt = rate_doubt(a.throw, rate_hz, lim.g_m_s2, lim.max_g_error)
        rate = f"; if {rate_hz:g} Hz is wrong, {doubt.split('? ')[1]}" if doubt else ""
        return Verdict(
            name,
            f"thrown marker's parabola: g = {g:.3f} m/s² ({100 * rel:+.2f} %), "
            f"fit rms {a.throw.rms_mm:.2f} mm{rate}",
            f"within {100 * lim.max_g_error:g} % of {lim.g_m_s2:g} m/s²",
            PASS if abs(rel) <= lim.max_g_error else FAIL,
        )
    return None


def trial_coverage(o: SessionOutputs, a: TrialAnalysis) -> float:
    """Mean coverage of the marker set's trajectories (of all when none is labelled)."""
    wanted = [m.coverage for m in a.markers if m.label in o.marker_names]
    values = wanted or [m.coverage for m in a.markers]
    return float(np.mean(values)) if values else math.nan


def _empty_verdict(o: SessionOutputs, name: str) -> Verdict:
    """A trial without trajectories: processed and empty (a warning), or not yet run."""
    figures = o.trial_figures(name)
    if not figures.processed:
        return Verdict(name, "no trajectories (not processed yet)", "", NONE)
    points, fields = figures.points or 0, figures.fields
    where = f" in its {fields} fields" if fields else ""
    text = (
        f"processed, no trajectories: {points} 3D points{where} "
        "(no marker seen by two cameras at once)"
    )
    return Verdict(name, text, "", WARN)


def trial_verdict(o: SessionOutputs, name: str, a: TrialAnalysis) -> Verdict:
    """Are all markers there (or, for a validation trial, does it pass)?"""
    lim = o.limits
    figures = o.trial_figures(name)
    if figures.failed:
        message = figures.failed.removeprefix(f"trial {name}: ")
        return Verdict(name, f"failed: {message}", "", FAIL)
    if not a.markers:
        return _empty_verdict(o, name)
    checked = _validation_verdict(name, a, lim, o.rate_hz)
    if checked is not None:
        return checked
    coverage = trial_coverage(o, a)
    cover = f"coverage {100 * coverage:.1f} %"
    filled = sum(m.filled for m in a.markers)
    limit = f"every marker of the set, coverage ≥ {100 * lim.min_coverage:g} %"
    if not o.marker_names:
        text = f"{len(a.markers)} trajectories (no marker set to label them), {cover}"
        return Verdict(name, text, limit, PASS if coverage >= lim.min_coverage else WARN)
    n_set = len(o.marker_names)
    if not figures.fits_marker_set:
        text = f"not labelled: its {len(a.markers)} trajectories do not fit the {n_set}-marker set"
        return Verdict(name, text, limit, WARN)
    missing = [m for m in figures.missing if m in o.marker_names]
    there = n_set - len(missing)
    text = f"{there}/{n_set} markers labelled, {cover}, {filled} samples filled"
    if missing:
        text += f"; missing {', '.join(missing)}"
    flagged = figures.flagged
    if flagged:
        text += f"; uncertain labels (check them): {', '.join(flagged)}"
    ok = not missing and not flagged and coverage >= lim.min_coverage
    return Verdict(name, text, limit, PASS if ok else WARN)
