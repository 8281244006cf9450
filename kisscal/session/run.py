"""``kisscal run``: the whole pipeline of a session, one stage calling the next."""

from __future__ import annotations

import logging
import os
import time
from pathlib import Path
from typing import Any

from kisscal.errors import KisscalError
from kisscal.io.config import SessionConfig, TrialConfig
from kisscal.io.files import write_json
from kisscal.io.frames import listing_once
from kisscal.io.store import SessionStore
from kisscal.io.summary import summarise
from kisscal.session.ahead import Ahead, blob_slot, detecting_ahead, image_job
from kisscal.session.inputs import writes_session
from kisscal.session.params import Overrides, stage_params
from kisscal.session.progress import Echo, quiet
from kisscal.session.report import report
from kisscal.session.runner import markers_detection, trial_stem
from kisscal.session.stages import Stage, StageCall, session_stages
from kisscal.session.trials import trial_frames_of
from kisscal.session.validate import SESSION, Problem, validate

#: Debug lines (``kisscal --verbose``): each stage's time.
_LOG = logging.getLogger(__name__)


@writes_session
def run(
    root: Path,
    overrides: Overrides | None = None,
    echo: Echo = quiet,
    workers: int | None = None,
    *,
    config: SessionConfig,
) -> dict[str, Any]:
    """``kisscal run``: the session's stages (:data:`~kisscal.session.stages.PIPELINE`):
    linearise, calibrate, then reconstruct and track every trial.

    ``workers`` is the number of detection processes (default: one per core).

    Detection and calibration are cached: re-running after changing a tracking
    parameter redoes only tracking. Writes ``out/summary.json`` and returns it.
    """
    with listing_once():  # the stages list the same frame folders: once a run
        return _run(Path(root), overrides, echo, workers, config)


def _run(
    root: Path, overrides: Overrides | None, echo: Echo, workers: int | None, config: SessionConfig
) -> dict[str, Any]:
    problems = validate(root, overrides, config=config)
    for p in problems:
        if p.warning:
            echo(f"  warning: {p}")
    problems = [p for p in problems if not p.warning]
    _stop_on_session_problems(problems, echo)
    broken = {p.scope: str(p) for p in problems}
    timings: dict[str, float] = {}
    trials = _in_order(config, echo)
    tried: list[bool] = []  # whether the trials' detection was started in the background

    def timed(name: str, stage: Stage, call: StageCall) -> None:
        t = time.perf_counter()
        if stage.name != "linearise" and not tried:  # the markers' survey needs the grid's
            args = (config, overrides, echo, workers, trials, broken)
            tried.append(_detect_trials_ahead(*args, call.ahead))
        stage.run(call)
        timings[name] = time.perf_counter() - t
        _LOG.debug("%s: %.2f s", name.removesuffix("_s"), timings[name])

    stages = session_stages(config)
    steps = len(stages)
    failures: dict[str, str] = {}
    with detecting_ahead() as ahead:
        for step, stage in enumerate(stages):
            if not stage.per_trial:
                echo(f"[{step + 1}/{steps}] {stage.title}")
                call = StageCall(config, overrides, echo, workers, ahead=ahead)
                timed(f"{stage.name}_s", stage, call)
        for trial in trials:
            if trial.name in broken:
                failures[trial.name] = broken[trial.name]
                echo(f"  skipped {broken[trial.name]}")
                continue
            call = StageCall(config, overrides, echo, workers, trial.name, ahead)
            try:
                for step, stage in enumerate(stages):
                    if stage.per_trial:
                        echo(f"[{step + 1}/{steps}] {stage.title}: {trial.name}")
                        timed(f"{stage.name}_{trial.name}_s", stage, call)
            except KisscalError as exc:  # one bad trial must not stop the others
                failures[trial.name] = f"trial {trial.name}: {exc}"
                echo(f"  failed {failures[trial.name]}")
    summary = summarise(root)
    summary["timings"] = {k: round(v, 3) for k, v in timings.items()}
    summary["failed_trials"] = failures
    write_json(SessionStore(root).summary_path, summary)
    report(root, echo=echo, config=config)
    if failures:  # the base class: trials fail for different reasons, each line says its own
        raise KisscalError(
            f"{len(failures)} of {len(config.trials)} trials failed "
            f"({'; '.join(failures.values())}); the other trials' outputs are complete"
        )
    return summary


def _detect_trials_ahead(
    config: SessionConfig,
    overrides: Overrides | None,
    echo: Echo,
    workers: int | None,
    trials: list[TrialConfig],
    broken: dict[str, str],
    ahead: Ahead | None,
) -> bool:
    """Start detecting the trials' images in the background (``ahead``, the run's
    :class:`~kisscal.session.ahead.Ahead`) where their blob caches are stale: the stages
    that follow run in this process meanwhile. The cameras' marker settings are derived
    first (the calibration, and every trial, read them kept). Nothing is started with one
    worker, nor when the settings cannot be derived (the stage that needs them says why).
    True when started."""
    if ahead is None or (workers or os.cpu_count() or 1) < 2:
        return False
    imaged = [t for t in trials if t.source in ("images", "video") and t.name not in broken]
    if not imaged:
        return False
    store = SessionStore(config.root)
    sizes = {c.id: c.size_px for c in config.cameras}
    try:
        detection = markers_detection(config, stage_params(config, overrides), echo, None, workers)
    except KisscalError:
        return False
    jobs = {}
    for trial in imaged:
        try:
            frames = trial_frames_of(config, trial)
        except KisscalError:  # said when the trial is processed
            continue
        for cam, seq in frames.items():
            slot = blob_slot(store, trial_stem(trial), cam, seq, trial.fields, detection[cam])
            if not store.is_current(*slot):
                jobs[slot] = image_job(seq, cam, sizes[cam], detection[cam], workers)
    return ahead.start(jobs, workers)


def _in_order(config: SessionConfig, echo: Echo) -> list[TrialConfig]:
    """The trials, the static one (``[markers] static``) first: its labelled positions
    are the template of the others."""
    static = config.markers.static if config.markers else None
    if static is None:
        return list(config.trials)
    echo(f"  static trial {static} first: its labelled positions are the others' template")
    return sorted(config.trials, key=lambda t: t.name != static)


def _stop_on_session_problems(problems: list[Problem], echo: Echo) -> None:
    """Refuse to start when the calibration inputs or parameters are broken."""
    fatal = [p for p in problems if p.scope == SESSION]
    for p in fatal if len(fatal) > 1 else ():  # one problem: the error line says it
        echo(f"  problem: {p}")
    if fatal:
        more = (
            f" (and {len(fatal) - 1} more: `kisscal validate` lists them)" if len(fatal) > 1 else ""
        )
        # the base class: validate's problems are of several kinds (missing, wrong)
        raise KisscalError(f"{fatal[0]}{more}; nothing was processed")
