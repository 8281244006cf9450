"""``kisscal report``: the session report, rebuilt from ``out/``."""

from __future__ import annotations

from pathlib import Path

from kisscal.errors import MissingDataError
from kisscal.io.store import SessionStore
from kisscal.session.figures import wait_for_figures
from kisscal.session.inputs import load_config, writes_session
from kisscal.session.params import stage_params
from kisscal.session.progress import Echo, quiet


@writes_session
def report(root: Path, echo: Echo = quiet) -> Path:
    """``kisscal report``: rebuild ``out/report.html`` from the session's outputs."""
    from kisscal.report.html import build_report  # matplotlib: only when a report is made

    config = load_config(root)  # a session folder, not just any path
    if not SessionStore(root).has_results():
        raise MissingDataError(f"{root}: nothing to report yet; run `kisscal run {root}` first")
    params = stage_params(config).report
    wait_for_figures()  # a stage's figures, drawn in the background, go into the page
    path = build_report(Path(root), params)
    echo(f"report: {path}")
    return path
