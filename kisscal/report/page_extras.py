"""Report sections at the end: timings, other figures, and the synthetic ground truth."""

from __future__ import annotations

from typing import Any

from kisscal.report.gather import SessionOutputs
from kisscal.report.htmlkit import Html, details, fmt, heading, join, png, section, table, tag

#: Figure name prefixes that belong to one camera or trial (``grid_cam1``, ...): a file
#: whose camera or trial is no longer in the session is stale and not shown.
PER_CAMERA = ("grid_",)
PER_TRIAL = ("epipolar_", "trajectories_", "segments_", "validation_")


def _scalar(v: Any) -> bool:
    return isinstance(v, int | float | str | bool) or v is None


def truth_table(truth: dict[str, Any]) -> Html:
    """One row per trial of the truth comparison; nested figures become columns."""
    rows: dict[str, dict[str, Any]] = {}
    mappings: list[Html] = []
    for trial, doc in truth.items():
        if not isinstance(doc, dict):
            continue
        flat: dict[str, Any] = {}
        for k, v in doc.items():
            if _scalar(v):
                flat[k] = v
            elif isinstance(v, dict) and all(_scalar(x) for x in v.values()):
                if k == "matched":
                    text = ", ".join(f"{a} → {b}" for a, b in v.items())
                    mappings.append(tag("p", f"{trial}: {text}", class_="note"))
                else:
                    flat.update({f"{k} {kk}": vv for kk, vv in v.items()})
        rows[trial] = flat
    columns: list[str] = []
    for flat in rows.values():
        columns += [k for k in flat if k not in columns]
    body = [[tag("b", t), *(fmt(f.get(c)) for c in columns)] for t, f in rows.items()]
    headers = ["trial", *(heading(c) for c in columns)]
    parts = [table(headers, body, range(1, len(headers)), "compact")]
    if mappings:
        parts.append(details("trajectory → true marker matches", join(mappings)))
    return join(parts)


def truth_section(o: SessionOutputs) -> Html:
    """Synthetic sessions only: the pipeline's results against the simulated truth."""
    truth = o.summary.get("truth")
    if not truth:
        return Html("")
    note = (
        "This session was simulated: the figures below compare the results with "
        "the truth the simulator knows. A real session has no such section."
    )
    body = truth_table(truth) if isinstance(truth, dict) else ""
    title = "Synthetic ground truth (simulated sessions only)"
    return section("truth", title, body, note, class_="truth")


def timings_section(o: SessionOutputs) -> Html:
    timings = o.summary.get("timings") or {}
    if not timings:
        return Html("")
    rows = [[k.removesuffix("_s").replace("_", " "), fmt(v, 1)] for k, v in timings.items()]
    return section("timings", "Processing time", table(["step", "seconds"], rows, (1,), "compact"))


def stale(o: SessionOutputs, name: str) -> bool:
    """A per-camera or per-trial figure whose camera or trial is gone."""
    for prefixes, names in ((PER_CAMERA, o.cameras), (PER_TRIAL, o.trials)):
        for p in prefixes:
            if name.startswith(p) and name[len(p) :] not in names:
                return True
    return False


def other_figures_section(o: SessionOutputs, used: set[str]) -> Html:
    """Figures written by stages the report has no section for (shown as they are)."""
    left = [n for n in o.figures if n not in used and not stale(o, n)]
    if not left:
        return Html("")
    figs = [png(o.figures[n], n, n.replace("_", " ")) for n in left]
    return section("figures", "Other figures", join(figs))


def notes_section(o: SessionOutputs) -> Html:
    if not o.notes:
        return Html("")
    return section("notes", "Files not read", tag("ul", join(tag("li", n) for n in o.notes)))
