"""The session report: ``out/report.html``, self-contained (figures embedded as PNG).

Stages save their figures to ``out/figures/`` when they run; the report gathers them
with the quality figures of ``out/summary.json``, so ``kisscal report`` can rebuild it
at any time without recomputing anything.
"""

from __future__ import annotations

import base64
import html
import json
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from kisscal.io.files import write_bytes, write_text

#: Figure files in report order: (file name prefix, section title).
SECTIONS = (
    ("grid_", "Grid linearisation: distorted and corrected dots, residual vectors"),
    ("dlt_residuals", "DLT reprojection residuals per camera"),
    ("rig", "Camera layout and calibration rods"),
    ("epipolar_", "One field with epipolar lines"),
    ("trajectories_", "3D trajectories"),
    ("segments_", "Segment lengths"),
)


def save_figure(fig: Figure, path: Path, dpi: int = 90) -> Path:
    """Write a matplotlib figure as PNG (atomically)."""
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    write_bytes(path, buf.getvalue())
    return path


def _rows(summary: dict[str, Any]) -> list[tuple[str, str, str]]:
    """Flatten the summary into (where, figure, value) rows."""
    rows: list[tuple[str, str, str]] = []

    def walk(prefix: str, obj: Any) -> None:
        if isinstance(obj, dict):
            for k, v in obj.items():
                walk(f"{prefix}.{k}" if prefix else str(k), v)
        elif isinstance(obj, list) and len(obj) > 6:
            rows.append((prefix.rsplit(".", 1)[0], prefix.rsplit(".", 1)[-1], f"{len(obj)} items"))
        else:
            value = f"{obj:.4g}" if isinstance(obj, float) else str(obj)
            where, _, name = prefix.rpartition(".")
            rows.append((where, name, value))

    walk("", summary)
    return rows


def build_report(root: Path) -> Path:
    """Write ``root/out/report.html`` from ``out/summary.json`` and ``out/figures/*.png``."""
    out = Path(root) / "out"
    summary_path = out / "summary.json"
    summary = json.loads(summary_path.read_text()) if summary_path.is_file() else {}
    figures = sorted((out / "figures").glob("*.png")) if (out / "figures").is_dir() else []
    parts = [
        "<!doctype html><html><head><meta charset='utf-8'>",
        f"<title>kisscal report: {html.escape(str(summary.get('session', root)))}</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}"
        "table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;padding:2px 6px}"
        "img{max-width:100%}</style></head><body>",
        f"<h1>kisscal session report: {html.escape(str(summary.get('session', '')))}</h1>",
        "<p>Residuals are <code>rms_px = sqrt(mean(du&sup2; + dv&sup2;))</code>, the RMS "
        "Euclidean distance in pixels (tools that report per-coordinate RMS give about "
        "1/&radic;2 of it).</p>",
    ]
    used: set[Path] = set()
    for prefix, title in SECTIONS:
        group = [f for f in figures if f.name.startswith(prefix)]
        if not group:
            continue
        parts.append(f"<h2>{html.escape(title)}</h2>")
        for f in group:
            used.add(f)
            data = base64.b64encode(f.read_bytes()).decode()
            parts.append(
                f"<p><img alt='{html.escape(f.stem)}' src='data:image/png;base64,{data}'></p>"
            )
    for f in figures:
        if f not in used:
            data = base64.b64encode(f.read_bytes()).decode()
            parts.append(
                f"<h2>{html.escape(f.stem)}</h2><p><img src='data:image/png;base64,{data}'></p>"
            )
    parts.append(
        "<h2>Quality figures</h2><table><tr><th>where</th><th>figure</th><th>value</th></tr>"
    )
    for where, name, value in _rows(summary):
        parts.append(
            f"<tr><td>{html.escape(where)}</td><td>{html.escape(name)}</td><td>{html.escape(value)}</td></tr>"
        )
    parts.append("</table></body></html>")
    path = out / "report.html"
    write_text(path, "\n".join(parts))
    return path
