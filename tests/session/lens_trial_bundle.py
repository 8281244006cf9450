"""Issue 25: the calibration of rods sessions with trials (the rods and the trials'
markers adjusted together, ``[dlt] trials_bundle``) against the volume's truth.

Run from the repository root on the rods sessions of
:mod:`tests.session.lens_model_acceptance` (``PRESET:SEED:FOLDER``)::

    python -m tests.session.lens_trial_bundle kiss:71:lens-model-acceptance/kiss71-rods

One line per session: the model the calibration chose, the held-out 3D error of the
volume's points inside and at the edges, the round trip through ``out/cameras.toml``
and the leave-one-rod-out mean. ``--off`` calibrates with the trials bundle off (the
rods' own choice), to compare; ``--trials stick,throw`` adjusts those trials only
(``[dlt] bundle_trials``); without it, the trials the session's first calibration
recorded in ``out/dlt/calibration.json`` (every trial, in a session that had none).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from kisscal import session
from kisscal.session.calibrated import current_rig
from kisscal.session.params import Overrides
from tests.session.lens_model_acceptance import OFF, _loo, round_trip_mm, volume_errors


def measure(preset: str, seed: int, root: Path, bundle: bool, trials: tuple[str, ...] = ()) -> dict:
    t0 = time.perf_counter()
    dlt = {"trials_bundle": bundle, "bundle_trials": trials}
    session.calibrate(root, **OFF, overrides=Overrides(dlt=dlt))
    seconds = time.perf_counter() - t0
    doc = json.loads((root / "out" / "dlt" / f"{current_rig(root).ids[0]}.json").read_text())
    errors = volume_errors(root, preset, seed)
    return {
        "rig": f"{preset}:{seed}",
        "model": doc.get("lens_models", {}).get("chosen"),
        **{k: round(v, 4) for k, v in errors.items()},
        "round_trip_mm": round(round_trip_mm(root, preset, seed), 4),
        "loo_mm": _loo(root),
        "seconds": round(seconds, 1),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rigs", nargs="+", help="PRESET:SEED:FOLDER")
    parser.add_argument("--off", action="store_true", help="[dlt] trials_bundle = false")
    parser.add_argument("--trials", default="", help="[dlt] bundle_trials, comma-separated")
    args = parser.parse_args()
    for arg in args.rigs:
        preset, seed, folder = arg.split(":", 2)
        trials = tuple(t for t in args.trials.split(",") if t)
        line = measure(preset, int(seed), Path(folder), not args.off, trials)
        print(json.dumps(line), flush=True)


if __name__ == "__main__":
    main()
