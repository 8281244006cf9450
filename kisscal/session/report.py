"""``kisscal report``: the session report, rebuilt from ``out/``."""

from __future__ import annotations

from pathlib import Path

from kisscal.session.inputs import load_config
from kisscal.session.progress import Echo, quiet


def report(root: Path, echo: Echo = quiet) -> Path:
    """``kisscal report``: rebuild ``out/report.html`` from the session's outputs."""
    from kisscal.report.html import build_report  # matplotlib: only when a report is made

    load_config(root)  # a session folder, not just any path
    path = build_report(Path(root))
    echo(f"report: {path}")
    return path
