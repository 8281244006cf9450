"""Report sections of the trials: markers, reconstruction, validation, gait, 3D viewer."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from kisscal.report.figures import stick_figure, throw_figure
from kisscal.report.gather import SessionOutputs
from kisscal.report.htmlkit import Html, badge, details, fmt, join, png, section, table, tag
from kisscal.report.status import FAIL, WARN, TrialAnalysis, Verdict, trial_coverage
from kisscal.report.viewer import trial_data, viewer_data, viewer_html


def _duration(o: SessionOutputs, name: str) -> str:
    t = o.trial_outputs[name].dense
    if t is None:
        return "–"
    return f"{t.n_fields} ({t.n_fields / o.rate_hz:.1f} s)"


def trial_table(
    o: SessionOutputs, analyses: dict[str, TrialAnalysis], verdicts: dict[str, Verdict]
) -> Html:
    """One row per trial: are the markers there, how complete, what was filled."""
    headers = [
        "trial",
        "status",
        "fields",
        "trajectories",
        "labelled",
        "coverage (%)",
        "gaps",
        "gap fields",
        "filled",
        "predicted",
        "3D points",
        "median rms (px)",
    ]
    rows, classes = [], []
    for name in o.trials:
        a = analyses[name]
        figures = o.trial_figures(name)
        ms = a.markers
        if figures.failed or not ms:
            rows.append([tag("b", name), badge(verdicts[name].state), verdicts[name].result])
            classes.append("failed" if figures.failed else None)
            continue
        labelled = "yes" if figures.fits_marker_set else "no"
        if figures.flagged:
            labelled = "uncertain: " + ", ".join(figures.flagged)
        if a.stick or a.throw:
            labelled = "validation trial"
        rows.append(
            [
                tag("b", name),
                badge(verdicts[name].state),
                _duration(o, name),
                fmt(len(ms)),
                labelled,
                fmt(100 * trial_coverage(o, a), 1),
                fmt(sum(m.gaps for m in ms)),
                fmt(sum(m.gap_fields for m in ms)),
                fmt(sum(m.filled for m in ms)),
                fmt(sum(m.predicted for m in ms)),
                fmt(figures.points),
                fmt(figures.rms_px_median),
            ]
        )
        classes.append(None)
    return table(headers, [_pad(r, len(headers)) for r in rows], range(2, 12), None, classes)


def _pad(row: list[Any], n: int) -> list[Any]:
    """A short row (a failed trial) gets its message across the remaining columns."""
    if len(row) >= n:
        return row
    return [*row[:-1], Html(f"{tag('span', row[-1], class_='message')}"), *[""] * (n - len(row))]


def cameras_table(o: SessionOutputs) -> Html:
    """3D points by the number of cameras that saw them, per trial."""
    by_n = {name: o.trial_figures(name).points_by_n_cameras for name in o.trials}
    counts = {name: v for name, v in by_n.items() if v is not None}
    if not counts:
        return Html("")
    width = max(len(v) for v in counts.values())
    used = [n for n in range(width) if any(n < len(v) and v[n] for v in counts.values())]
    rows = []
    for name, v in counts.items():
        total = max(sum(v), 1)
        cells = [
            f"{v[n] if n < len(v) else 0} ({100 * (v[n] if n < len(v) else 0) / total:.0f} %)"
            for n in used
        ]
        rows.append([tag("b", name), *cells])
    return join(
        [
            tag("h3", "3D points by the number of cameras that saw them"),
            table(["trial", *(f"{n} cameras" for n in used)], rows, range(1, len(used) + 1)),
        ]
    )


def fill_list(fills: tuple[tuple[int, int, str], ...], most: int = 8) -> str:
    """The filled runs of a trajectory as text: ``120+14 rigid, 300+3 spline, ...``."""
    text = ", ".join(f"{first}+{n} {how}" for first, n, how in fills[:most])
    return text + (f", ... ({len(fills)} in all)" if len(fills) > most else "") or "-"


def marker_details(
    o: SessionOutputs, a: TrialAnalysis, used: set[str], open_: bool = False
) -> Html:
    """Per trajectory presence, the segment lengths and the trial's figures, folded
    (unfolded with ``open_``: a trial to check shows which trajectory is short at once)."""
    parts: list[Any] = []
    rows = [
        [
            tag("b", m.label),
            fmt(100 * m.coverage_measured, 1),
            fmt(100 * m.coverage, 1),
            fmt(m.gaps),
            fmt(m.gap_fields),
            fmt(m.measured),
            fmt(m.filled - m.filled_rigid - m.filled_pattern),
            fmt(m.filled_rigid),
            fmt(m.filled_pattern),
            fmt(m.predicted),
            fill_list(m.fills),
        ]
        for m in a.markers
    ]
    parts.append(
        table(
            [
                "trajectory",
                "coverage before filling (%)",
                "after (%)",
                "gaps",
                "gap fields",
                "measured",
                "filled: spline",
                "rigid body",
                "pattern",
                "predicted",
                "each gap filled (first field, fields, how)",
            ],
            rows,
            range(1, 10),
            "compact",
        )
    )
    if a.segments:
        seg_rows = [
            [f"{s.a}–{s.b}", fmt(s.mean_mm, 1), fmt(s.sd_mm, 2), fmt(s.range_mm, 2), fmt(s.samples)]
            for s in a.segments
        ]
        worst = max(s.sd_mm for s in a.segments)
        parts.append(tag("h4", f"Rigid segments: length SD at most {worst:.2f} mm"))
        head = ["segment", "mean length (mm)", "SD (mm)", "max − min (mm)", "fields"]
        parts.append(table(head, seg_rows, range(1, 5), "compact"))
        fig = f"segments_{a.name}"
        if fig in o.figures:
            used.add(fig)
            caption = "Length over time: measured (solid) and Kalman-corrected (dashed)."
            curves = png(o.figures[fig], fig, caption)
            parts.append(details("length curves of every segment", curves))
    fig = f"trajectories_{a.name}"
    if fig in o.figures:
        used.add(fig)
        parts.append(png(o.figures[fig], fig, f"{a.name}: trajectories in three views (mm)."))
    return details(
        f"{a.name}: every trajectory, segment lengths and views", join(parts), open_=open_
    )


def trials_section(
    o: SessionOutputs,
    analyses: dict[str, TrialAnalysis],
    verdicts: dict[str, Verdict],
    used: set[str],
) -> Html:
    if not o.trials:
        return Html("")
    parts: list[Any] = [trial_table(o, analyses, verdicts)]
    parts += [
        marker_details(o, analyses[n], used, open_=verdicts[n].state in (WARN, FAIL))
        for n in o.trials
        if analyses[n].markers
    ]
    parts.append(cameras_table(o))
    for name in o.trials:
        fig = f"epipolar_{name}"
        if fig in o.figures:
            used.add(fig)
            parts.append(tag("h3", f"Matching check: one field of {name}"))
            parts.append(png(o.figures[fig], fig, EPIPOLAR_CAPTION))
    note = (
        "Coverage: share of the trial's fields in which a trajectory has a sample. Gaps: "
        "missing stretches inside a trajectory. Filled: samples interpolated across gaps."
    )
    return section("trials", "Trials and markers", join(parts), note)


EPIPOLAR_CAPTION = (
    "Each panel is one camera's image. A ring is a blob matched to a 3D marker (same colour "
    "in every camera); a cross is a blob left unmatched. The lines are the epipolar lines "
    "of that marker's blobs in the other cameras: with a good calibration all lines of a "
    "colour pass through the ring of that colour."
)


def validation_section(
    o: SessionOutputs,
    analyses: dict[str, TrialAnalysis],
    draw: Callable[[str, tuple, Callable[[], Figure]], bytes],
    used: set[str],
) -> Html:
    """Stick length and thrown-marker g, drawn here from the trajectories.

    ``draw(name, key, make)`` returns the PNG of ``make()``, drawn only when ``key`` (the
    data the figure shows) differs from the last time.
    """
    parts = []
    lim = o.limits
    for name in o.trials:
        a, fig = analyses[name], f"validation_{name}"
        used.add(fig)
        if a.stick is not None:
            s = a.stick
            key = ("stick", name, s.a, s.b, s.length_mm, s.true_mm)
            data = draw(fig, key, lambda s=s, name=name: stick_figure(s, name))
            caption = (
                f"{name}: distance between the stick's markers over time; the dashed line is "
                f"the true length ({lim.stick_length_mm:g} mm, Shafiq et al. 2001)."
            )
            parts.append(png(data, f"stick {name}", caption))
        elif a.throw is not None:
            t = a.throw
            key = ("throw", name, t.label, t.time_s, t.xyz_mm, lim.g_m_s2)
            data = draw(fig, key, lambda t=t, name=name: throw_figure(t, lim.g_m_s2, name))
            caption = (
                f"{name}: height of the thrown marker with the parabola fitted to it; g is "
                "twice its t² coefficient (Shafiq et al. 2001)."
            )
            parts.append(png(data, f"throw {name}", caption))
    if not parts:
        return Html("")
    return section("validation", "Validation: stick length and thrown marker", join(parts))


def viewer_section(o: SessionOutputs, analyses: dict[str, TrialAnalysis]) -> Html:
    """The 3D viewer over every trial with trajectories; segments (or the stick) joined."""
    trials = {}
    for name in o.trials:
        t, a = o.trial_outputs[name], analyses[name]
        if t.dense is None or not t.dense.labels:
            continue
        pairs = list(o.segments) + ([(a.stick.a, a.stick.b)] if a.stick else [])
        trials[name] = trial_data(name, t.dense, o.rate_hz, pairs, o.limits.viewer_samples)
    if not trials:
        return Html("")
    cams = {c: o.camera_figures(c).centre_mm for c in o.cameras}
    return section("viewer", "3D viewer", viewer_html(viewer_data(trials, cams)))


def gait_section(o: SessionOutputs, used: set[str]) -> Html:
    """Gait events and spatiotemporal parameters per trial, when the gait stage wrote them."""
    parts = []
    for name in o.trials:
        t = o.trial_outputs[name]
        for title, tab in (
            ("gait events", t.events),
            ("spatiotemporal parameters", t.spatiotemporal),
        ):
            if not tab:
                continue
            cols = list(tab)
            n = len(tab[cols[0]]) if cols else 0
            numeric = [i for i, c in enumerate(cols) if np.asarray(tab[c]).dtype.kind == "f"]
            shown = [_whole_as_int(tab[c]) for c in cols]
            rows = [[fmt(col[r]) for col in shown] for r in range(n)]
            parts.append(tag("h3", f"{name}: {title}"))
            parts.append(table(cols, rows, numeric, "compact"))
    for fig in sorted(o.figures):
        if fig.startswith("gait"):
            used.add(fig)
            parts.append(png(o.figures[fig], fig, fig.replace("_", " ")))
    if not parts:
        return Html("")
    return section("gait", "Gait events and parameters", join(parts))


def _whole_as_int(column: Any) -> list[Any]:
    """A table column for :func:`fmt`: whole numbers (frames, counts) as integers."""
    values = np.asarray(column)
    if values.dtype.kind != "f":
        return values.tolist()
    return [int(x) if x.is_integer() and abs(x) < 1e9 else float(x) for x in values.tolist()]
