"""The session report: ``out/report.html``, one self-contained page for people.

The first screen answers "did the calibration pass and are all markers there?": a status
block with pass / fail of every check and its limit, one line per camera and per trial.
Below it: the calibration table, the trials' marker table, the validation plots (stick
length, thrown marker), an offline 3D viewer, then detail sections that appear only when
their data exist (detection settings, wand, gait) and, for simulated sessions, the truth.

Stages save their figures to ``out/figures/`` when they run; the report draws only the
figures that need the trajectories on disk (stick, thrown marker), so ``kisscal report``
rebuilds the page at any time without re-running a stage. Everything is inlined: images
as data URIs, the viewer's script and data; the page makes no network request.
"""

from __future__ import annotations

import html
import io
from collections.abc import Callable
from datetime import datetime
from pathlib import Path

import matplotlib
from matplotlib.figure import Figure

from kisscal.io.files import write_bytes, write_text
from kisscal.io.store import SessionStore
from kisscal.report.gather import SessionOutputs, gather
from kisscal.report.htmlkit import Html, badge, join, table, tag
from kisscal.report.page_calibration import calibration_section, detection_section, wand_section
from kisscal.report.page_extras import (
    notes_section,
    other_figures_section,
    timings_section,
    truth_section,
)
from kisscal.report.page_trials import (
    gait_section,
    trials_section,
    validation_section,
    viewer_section,
)
from kisscal.report.params import ReportParams
from kisscal.report.status import (
    FAIL,
    PASS,
    WARN,
    TrialAnalysis,
    Verdict,
    analyse_trial,
    camera_verdicts,
    rig_verdict,
    trial_verdict,
    worst,
)

#: matplotlib settings a stage figure is drawn with (``matplotlib.rc_context``): panel
#: titles stay where they are put (1.0 axes height, plus the pad) instead of matplotlib
#: measuring each panel's tick labels before placing its title, a fifth of a many-panel
#: figure's processor time; no kisscal figure has tick labels above a panel.
FIGURE_RC = {"axes.titley": 1.0}


def figure_png(fig: Figure, dpi: int = 90) -> bytes:
    """A matplotlib figure as PNG bytes (256-colour palette when Pillow is there)."""
    buf = io.BytesIO()
    try:
        from PIL import Image  # Pillow: matplotlib's own PNG writer
    except ImportError:
        fig.savefig(buf, format="png", dpi=dpi)
        return buf.getvalue()
    # The canvas's pixels as they are, not written as PNG and read back for the palette.
    # Their size is that of the Agg canvas savefig drew on: matplotlib rounds a side
    # within 1e-8 px of a whole pixel up, so the size in inches times ``dpi``, truncated,
    # can be a pixel short (8.4 in at 90 dpi), which drew such a figure a second time.
    fig.savefig(buf, format="rgba", dpi=dpi)
    drawn = getattr(fig.canvas, "renderer", None)
    size = (
        (int(drawn.width), int(drawn.height))
        if drawn is not None
        else tuple(int(side) for side in fig.get_size_inches() * dpi)
    )
    if len(buf.getvalue()) == 4 * size[0] * size[1]:
        canvas = Image.frombuffer("RGBA", size, buf.getvalue(), "raw", "RGBA", 0, 1)
    else:  # a canvas of another size: as PNG, the way matplotlib writes it
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=dpi)
        canvas = Image.open(buf)
    # Plots hold few colours: a 256-colour palette keeps them sharp at a quarter the size.
    image = canvas.convert("RGB").quantize(256, method=Image.Quantize.FASTOCTREE)
    small = io.BytesIO()
    image.save(small, format="png")  # optimize=True: 10 % smaller, 3x the time
    return small.getvalue()


def save_figure(fig: Figure, path: Path) -> None:
    """Write a matplotlib figure as PNG (atomically)."""
    write_bytes(path, figure_png(fig))


CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:#1d232a;
 max-width:1200px;margin:0 auto;padding:0 18px 40px;line-height:1.4;font-size:15px}
h1{font-size:24px;margin:18px 0 2px} h2{font-size:20px;margin:34px 0 8px;
 border-bottom:2px solid #d9dee3;padding-bottom:3px} h3{font-size:16px;margin:20px 0 6px}
h4{font-size:14px;margin:14px 0 4px}
.sub{color:#5b6670;margin:0 0 12px}.note{color:#5b6670;font-size:13px;margin:4px 0 10px}
nav{font-size:13px;margin:6px 0 0;color:#5b6670} nav a{margin-right:12px;color:#2a62a8}
table{border-collapse:collapse;font-size:13px;margin:6px 0 12px}
th,td{border-bottom:1px solid #e1e5e9;padding:4px 9px;text-align:left;vertical-align:top}
th{background:#f3f5f7;font-weight:600} td.num,th.num{text-align:right;
 font-variant-numeric:tabular-nums} tr.failed td{background:#fdf0ef}
table.compact td,table.compact th{padding:2px 7px}
.badge{display:inline-block;min-width:46px;text-align:center;border-radius:4px;
 font-weight:700;font-size:12px;padding:1px 6px;color:#fff}
.badge.pass{background:#2e8540}.badge.warn{background:#c77700}.badge.fail{background:#c0392b}
.badge.none{background:#8a949d}
.tiles{display:flex;gap:12px;flex-wrap:wrap;margin:10px 0 12px}
.tile{flex:1 1 260px;border-radius:8px;padding:10px 14px;border:1px solid #d9dee3;
 border-left-width:8px}
.tile.pass{border-left-color:#2e8540;background:#f1f8f2}
.tile.warn{border-left-color:#c77700;background:#fdf6ea}
.tile.fail{border-left-color:#c0392b;background:#fdf0ef}
.tile.none{border-left-color:#8a949d;background:#f5f6f7}
.tile .head{font-size:13px;text-transform:uppercase;letter-spacing:.04em;color:#5b6670}
.tile .big{font-size:22px;font-weight:700;margin:2px 0}
.tile .line{font-size:13px}
table.status td:nth-child(2){font-weight:600;white-space:nowrap}
table.status td:last-child{color:#5b6670}
figure{margin:8px 0 16px} figure img{max-width:100%;border:1px solid #eef0f2}
figcaption{font-size:13px;color:#5b6670;max-width:900px}
details{margin:6px 0;border:1px solid #e1e5e9;border-radius:6px;padding:4px 10px}
details>summary{cursor:pointer;font-weight:600;padding:2px 0}
.viewer{border:1px solid #d9dee3;border-radius:8px;padding:8px}
.viewer-bar{display:flex;flex-wrap:wrap;gap:10px;align-items:center;font-size:13px;
 margin-bottom:6px} .viewer canvas{width:100%;height:560px;background:#fbfcfd;
 display:block;cursor:grab} .mono{font-family:ui-monospace,monospace;font-size:12px}
.message{color:#8c2a1f}
section.truth{border-top:4px dashed #8a949d;margin-top:40px;padding-top:4px}
section.truth h2{color:#5b6670}
"""

_TILE_WORD = {PASS: "PASS", WARN: "CHECK", FAIL: "FAIL", "none": "NO DATA"}


def _tile(head: str, state: str, lines: list[str]) -> Html:
    return tag(
        "div",
        join(
            [
                tag("div", head, class_="head"),
                tag("div", _TILE_WORD.get(state, state), class_="big"),
                join(tag("div", line, class_="line") for line in lines),
            ]
        ),
        class_=f"tile {state}",
    )


def _problems(verdicts: list[Verdict]) -> list[str]:
    return [f"{v.scope}: {v.result}" for v in verdicts if v.state in (WARN, FAIL)]


def status_section(
    o: SessionOutputs,
    cams: list[Verdict],
    rig: Verdict | None,
    trials: list[Verdict],
    analyses: dict[str, TrialAnalysis],
) -> Html:
    """The first screen: three tiles (calibration, markers, validation) and every line."""
    calibration = cams + ([rig] if rig else [])
    cal_state = worst([v.state for v in calibration])
    good = sum(v.state == PASS for v in cams)
    cal_lines = [f"{good} of {len(cams)} cameras within limits"]
    if rig:
        cal_lines.append(f"3D error, {rig.result}")
    cal_lines += _problems(calibration)[:3]
    is_val = {n: bool(analyses[n].stick or analyses[n].throw) for n in o.trials}
    gait = [v for v in trials if not is_val.get(v.scope)]
    val = [v for v in trials if is_val.get(v.scope)]
    complete = sum(v.state == PASS for v in gait)
    tiles = [_tile("Calibration", cal_state, cal_lines)]
    if gait:
        lines = [f"all markers there in {complete} of {len(gait)} trials"]
        lines += _problems(gait)[:3]
        tiles.append(_tile("Markers", worst([v.state for v in gait]), lines))
    if val:
        lines = [f"{v.scope}: {v.result}" for v in val]
        tiles.append(_tile("Validation", worst([v.state for v in val]), lines))
    rows = [[badge(v.state), v.scope, v.result, v.limit] for v in calibration + trials]
    head = ["", "check", "result", "limit"]
    body = join([tag("div", join(tiles), class_="tiles"), table(head, rows, (), "status")])
    return tag("section", body, id="status")


def _header(o: SessionOutputs) -> Html:
    summary_path = SessionStore(o.root).summary_path
    when = (
        datetime.fromtimestamp(summary_path.stat().st_mtime).strftime("%Y-%m-%d %H:%M")
        if summary_path.is_file()
        else "not run"
    )
    sub = (
        f"{len(o.cameras)} cameras · {len(o.trials)} trials · {o.rate_hz:g} Hz · "
        f"processed {when} · {o.root}"
    )
    return join([tag("h1", f"kisscal session report: {o.session}"), tag("p", sub, class_="sub")])


_NAV = (
    ("status", "Status"),
    ("calibration", "Calibration"),
    ("detection", "Detection"),
    ("wand", "Wand"),
    ("trials", "Trials"),
    ("validation", "Validation"),
    ("viewer", "3D viewer"),
    ("gait", "Gait"),
    ("figures", "Other figures"),
    ("timings", "Timings"),
    ("truth", "Synthetic truth"),
)


def render(o: SessionOutputs, draw: Callable[[str, tuple, Callable[[], Figure]], bytes]) -> str:
    """The report page of gathered outputs.

    ``draw(name, key, make)`` returns the PNG of a figure the report draws itself (see
    :func:`build_report`, which keeps them in ``out/figures/`` keyed by their data).
    """
    analyses = {n: analyse_trial(o, o.trial_outputs[n]) for n in o.trials}
    cams = camera_verdicts(o)
    rig = rig_verdict(o)
    trials = [trial_verdict(o, n, analyses[n]) for n in o.trials]
    used: set[str] = set()
    body = [
        calibration_section(o, {v.scope: v for v in cams}, used),
        detection_section(o),
        wand_section(o, used),
        trials_section(o, analyses, {v.scope: v for v in trials}, used),
        validation_section(o, analyses, draw, used),
        viewer_section(o, analyses),
        gait_section(o, used),
    ]
    body += [other_figures_section(o, used), timings_section(o), notes_section(o)]
    body.append(truth_section(o))
    status = status_section(o, cams, rig, trials, analyses)
    present = [(k, t) for k, t in _NAV if any(f'id="{k}"' in s for s in [status, *body])]
    nav = tag("nav", join(tag("a", t, href=f"#{k}") for k, t in present))
    page = join([_header(o), nav, status, *body])
    title = html.escape(f"kisscal report: {o.session}")
    return (
        "<!doctype html>\n<html lang='en'><head><meta charset='utf-8'>"
        "<meta name='viewport' content='width=device-width, initial-scale=1'>"
        f"<title>{title}</title><style>{CSS}</style></head><body>\n{page}\n</body></html>\n"
    )


def build_report(root: Path, params: ReportParams | None = None) -> Path:
    r"""Write ``root/out/report.html`` from the session's outputs; return its path.

    Parameters
    ----------
    root : Path
        The session folder (with ``session.toml`` and ``out/``).
    params : ReportParams, optional
        Limits of the status block; ``out/limits.json`` (``kisscal check`` limits)
        overrides the calibration ones.

    References
    ----------
    Shafiq, Tümer, Güler 2001 (stick and thrown-marker validation); Kolahi et al. 2007
    (the 3D error of a real lab's DLT the default limit is set from).

    Examples
    --------
    >>> import json, tempfile
    >>> root = Path(tempfile.mkdtemp())
    >>> _ = (root / "session.toml").write_text(
    ...     '[session]\nname = "lab"\nrate_hz = 50\n[[cameras]]\nid = "cam1"\n')
    >>> (root / "out").mkdir()
    >>> summary = {"cameras": {"cam1": {"dlt": {"method": "dlt", "rms_px": 0.12}}}}
    >>> _ = (root / "out" / "summary.json").write_text(json.dumps(summary))
    >>> page = build_report(root).read_text()
    >>> page.index('id="status"') < page.index('id="calibration"'), "DLT rms 0.120 px" in page
    (True, True)
    """
    outputs = gather(Path(root), params)
    store = SessionStore(root)

    def draw(name: str, key_parts: tuple, make: Callable[[], Figure]) -> bytes:
        path = store.figure_path(name)
        key = store.key("report figure", *key_parts)
        if not store.is_current(path, key):
            with matplotlib.rc_context(FIGURE_RC):
                write_bytes(path, figure_png(make()))
            store.mark_current(path, key)
        return path.read_bytes()

    path = store.report_path
    write_text(path, render(outputs, draw))
    return path
