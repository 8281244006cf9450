"""``kisscal run``: the whole pipeline of a session, one stage calling the next."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from kisscal.io.files import write_json
from kisscal.session.calibrate import calibrate
from kisscal.session.inputs import load_config, out_dir
from kisscal.session.linearise import linearise
from kisscal.session.params import Overrides, stage_params
from kisscal.session.progress import Echo, quiet
from kisscal.session.reconstruct import reconstruct
from kisscal.session.report import report
from kisscal.session.summary import summarise
from kisscal.session.track import track


def run(
    root: Path,
    overrides: Overrides | None = None,
    echo: Echo = quiet,
    workers: int | None = None,
) -> dict[str, Any]:
    """``kisscal run``: linearise, calibrate, then reconstruct and track every trial.

    ``workers`` is the number of detection processes (default: one per core).

    Detection and calibration are cached: re-running after changing a tracking
    parameter redoes only tracking. Writes ``out/summary.json`` and returns it.
    """
    root = Path(root)
    config = load_config(root)
    stage_params(config, overrides)  # fail fast on bad parameters, before any work
    timings: dict[str, float] = {}

    def timed(name: str, step: Any, *args: Any, **kwargs: Any) -> None:
        t = time.perf_counter()
        step(*args, **kwargs)
        timings[name] = time.perf_counter() - t

    echo("[1/4] linearisation")
    timed("linearise_s", linearise, root, overrides=overrides, echo=echo)
    echo("[2/4] calibration")
    timed("calibrate_s", calibrate, root, overrides=overrides, echo=echo, workers=workers)
    for trial in config.trials:
        echo(f"[3/4] reconstruction: {trial.name}")
        timed(
            f"reconstruct_{trial.name}_s", reconstruct, root, trial.name, overrides, echo, workers
        )
        echo(f"[4/4] tracking: {trial.name}")
        timed(f"track_{trial.name}_s", track, root, trial.name, overrides, echo=echo)
    summary = summarise(root)
    summary["timings"] = {k: round(v, 3) for k, v in timings.items()}
    write_json(out_dir(root) / "summary.json", summary)
    report(root, echo=echo)
    return summary
