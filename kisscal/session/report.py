"""``kisscal report``: the session report, rebuilt from ``out/``."""

from __future__ import annotations

from pathlib import Path

from kisscal.errors import MissingDataError
from kisscal.io.config import SessionConfig
from kisscal.io.store import SessionStore
from kisscal.report.params import ReportParams
from kisscal.session.figures import after_figures, wait_for_figures
from kisscal.session.inputs import writes_session
from kisscal.session.params import stage_params
from kisscal.session.progress import Echo, quiet


@writes_session
def report(root: Path, echo: Echo = quiet, *, config: SessionConfig) -> Path:
    """``kisscal report``: rebuild ``out/report.html`` from the session's outputs (``config``:
    the session's, read from ``root`` when the caller has none)."""
    if not SessionStore(root).has_results():
        raise MissingDataError(f"{root}: nothing to report yet; run `kisscal run {root}` first")
    params = stage_params(config).report
    # built in the figure process, after the stages' figures (which go into the page):
    # matplotlib is imported there already
    path = after_figures(_build, Path(root), params)
    wait_for_figures()  # a figure that failed (a bug) says so
    echo(f"report: {path}")
    return path


def _build(root: Path, params: ReportParams) -> Path:
    """:func:`kisscal.report.html.build_report`, imported where it runs (with matplotlib,
    some 1.3 s of import the session's process is spared: :func:`after_figures`)."""
    from kisscal.report.html import build_report

    return build_report(root, params)
