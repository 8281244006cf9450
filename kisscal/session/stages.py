"""The stages of a session, declared once: what each runs on, with which parameters,
what it writes, and the command that runs it.

``kisscal run`` is this table read top to bottom: the session stages once, then the
trial stages for each trial, each trial on its own (a failed trial does not stop the
others). The documentation's table of stages and the test of every stage's outputs
(``tests/session/test_stages.py``) read it too, so a stage added here is run, documented
and checked in one step.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kisscal.io.config import SessionConfig
from kisscal.session.ahead import Ahead
from kisscal.session.calibrate import calibrate
from kisscal.session.inputs import needs_calibration, writes_session
from kisscal.session.linearise import linearise
from kisscal.session.params import Overrides
from kisscal.session.progress import Echo, quiet
from kisscal.session.reconstruct import RECONSTRUCT
from kisscal.session.runner import run_trial
from kisscal.session.track import track


@dataclass(frozen=True)
class StageCall:
    """What one run of a stage is given: the session (read once, by ``kisscal run``), its
    overrides, where to say what happens, the number of worker processes, for a trial
    stage the trial, and the trials' blobs the run detects in the background
    (:class:`~kisscal.session.ahead.Ahead`)."""

    config: SessionConfig
    overrides: Overrides | None
    echo: Echo
    workers: int | None
    trial: str = ""
    ahead: Ahead | None = None


def _always(config: SessionConfig) -> bool:
    return True


@dataclass(frozen=True)
class Stage:
    """One stage of a session.

    Attributes
    ----------
    name : str
        The command that runs it alone (``kisscal <name>``).
    title : str
        Its heading in ``kisscal run``'s progress.
    per_trial : bool
        Run once per trial (else once for the session).
    params : tuple of str
        The members of :class:`~kisscal.session.params.StageParams` it uses.
    outputs : tuple of str
        What it writes, by the store's names: properties of
        :class:`~kisscal.io.store.SessionStore` (``linearisation_path``, ...) or, for a
        trial stage, of :class:`~kisscal.io.store.TrialFiles` (``points3d``, ...).
    run : callable
        Runs it: ``run(StageCall)``.
    needed : callable
        Whether a session needs it at all (a session of C3D trials is neither linearised
        nor calibrated).
    """

    name: str
    title: str
    per_trial: bool
    params: tuple[str, ...]
    outputs: tuple[str, ...]
    run: Callable[[StageCall], object]
    needed: Callable[[SessionConfig], bool] = _always


def _linearise(call: StageCall) -> object:
    o, echo, workers = call.overrides, call.echo, call.workers
    return linearise(call.config.root, overrides=o, echo=echo, workers=workers, config=call.config)


def _calibrate(call: StageCall) -> object:
    o, echo, workers, config = call.overrides, call.echo, call.workers, call.config
    return calibrate(
        config.root, overrides=o, echo=echo, workers=workers, config=config, ahead=call.ahead
    )


@writes_session
def reconstruct(
    root: Path,
    trial_name: str,
    overrides: Overrides | None = None,
    echo: Echo = quiet,
    workers: int | None = None,
    *,
    config: SessionConfig,
) -> Any:
    """``kisscal reconstruct``: 3D points of one trial, written to ``points3d.csv`` (the
    runner hands :mod:`kisscal.session.reconstruct` the trial's blobs)."""
    return run_trial(RECONSTRUCT, config, trial_name, overrides, echo, workers)


def _reconstruct(call: StageCall) -> object:  # kisscal run holds the session's lock
    o, echo, workers = call.overrides, call.echo, call.workers
    return run_trial(RECONSTRUCT, call.config, call.trial, o, echo, workers, call.ahead)


def _track(call: StageCall) -> object:
    return track(call.config.root, call.trial, call.overrides, echo=call.echo, config=call.config)


#: ``kisscal run``, in order.
PIPELINE: tuple[Stage, ...] = (
    Stage(
        "linearise",
        "linearisation",
        per_trial=False,
        params=("detection", "grid"),
        outputs=("linearisation_path", "detection_path"),
        run=_linearise,
        needed=needs_calibration,
    ),
    Stage(
        "calibrate",
        "calibration",
        per_trial=False,
        params=("detection", "dlt", "wand", "target", "recon"),
        outputs=("dlt_path", "dltdv_path", "cameras_toml_path", "exports_path"),
        run=_calibrate,
        needed=needs_calibration,
    ),
    Stage(
        "reconstruct",
        "reconstruction",
        per_trial=True,
        params=("detection", "recon"),
        outputs=("points3d", "points2d", "recon"),
        run=_reconstruct,
    ),
    Stage(
        "track",
        "tracking",
        per_trial=True,
        params=("tracking", "gait", "report"),
        outputs=("trajectories", "trajectory_cameras", "tracking"),
        run=_track,
    ),
)


def session_stages(config: SessionConfig) -> tuple[Stage, ...]:
    """The stages ``config`` needs, in order."""
    return tuple(s for s in PIPELINE if s.needed(config))
