"""Runs a lab session: finds each stage's inputs in the session folder, caches its
results under ``out/cache`` keyed by a hash of inputs and parameters, and writes every
output atomically through :mod:`kisscal.io`.

The stages (:mod:`kisscal.detect`, :mod:`kisscal.grid`, :mod:`kisscal.dlt`,
:mod:`kisscal.recon`, :mod:`kisscal.tracking`) work on arrays; one module here runs each
of them for a session. The CLI (:mod:`kisscal.cli`) is a thin layer over these functions;
tests call them directly.

Modules: :mod:`~kisscal.session.params` (parameters and CLI overrides),
:mod:`~kisscal.session.inputs` (config, output folder, cache-key parts, figures),
:mod:`~kisscal.session.progress`, one module per stage (``detection``, ``linearise``,
``calibrate`` with its ``routes``, ``reconstruct``, ``track``), ``calibrated`` (the
session's calibrated rig, :func:`current_rig`), ``trials`` (a trial's 2D sources),
``runner`` (each camera's detection settings and blobs, and the run of a trial stage),
``exports`` (the calibration for anipose, Pose2Sim, DLTdv8 and OpenCV), ``summary``
(``summary.json``, ``check``), ``report``, ``run``, ``batch`` (Dask), ``validate`` and
``init``; ``synth`` writes (``synth_session``, ``synth_target``) and scores synthetic
sessions (the rigs themselves, :mod:`kisscal.synth`, never touch files) and ``demo``
runs one end to end.
"""

from __future__ import annotations

from typing import Any

from kisscal.io.store import SessionStore
from kisscal.io.summary import summarise
from kisscal.session.calibrate import calibrate
from kisscal.session.calibrated import current_rig
from kisscal.session.detection import detect_images
from kisscal.session.exports import export
from kisscal.session.init import init_session
from kisscal.session.linearise import linearise
from kisscal.session.params import Overrides, StageParams, stage_params
from kisscal.session.progress import Progress, reporting_progress
from kisscal.session.report import report
from kisscal.session.run import run
from kisscal.session.stages import reconstruct
from kisscal.session.summary import CheckFailure, check
from kisscal.session.track import track
from kisscal.session.validate import Problem, validate

# Imported on first use: the demo and synthesis are not needed to process a real session,
# and the batch imports Dask.
_LAZY = {
    "batch": "kisscal.session.batch",
    "demo": "kisscal.session.demo",
    "synthesise": "kisscal.session.synth",
    "synthesise_target": "kisscal.session.synth",
    "evaluate": "kisscal.session.synth",
    "default_walking5_path": "kisscal.session.synth",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'kisscal.session' has no attribute {name!r}")


__all__ = [
    "CheckFailure",
    "Overrides",
    "Problem",
    "Progress",
    "SessionStore",
    "StageParams",
    "batch",
    "calibrate",
    "check",
    "current_rig",
    "default_walking5_path",
    "demo",
    "detect_images",
    "evaluate",
    "export",
    "init_session",
    "linearise",
    "reconstruct",
    "report",
    "reporting_progress",
    "run",
    "stage_params",
    "summarise",
    "synthesise",
    "synthesise_target",
    "track",
    "validate",
]
