"""Issue 25: can a judge on the rods alone choose the camera model? Each judge's choice
against the volume's truth.

Run from the repository root on the rods sessions of
:mod:`tests.session.lens_model_acceptance` (``PRESET:SEED:FOLDER``)::

    python -m tests.session.lens_rods_judges kiss:71:lens-model-acceptance/kiss71-rods

Per session, every model of :data:`kisscal.dlt.select.MODELS` is fitted on the rods alone
and scored on the held-out lab points of the volume (inside and edges, as
:func:`~tests.session.lens_model_acceptance.volume_errors`), and its held-out rod markers
are kept by fold design (each rod out; one marker of every rod out, staggered). Each judge
then picks the model with the least weighed score (``1 + margin`` per unknown beyond the
DLT's 11): the RMS of either design, their geometric mean (the default's score, before
its one-standard-error rule), the RMS of the per-rod mean squared errors (a left-out rod's
markers share one offset: four measurements, not 24) and either design's median. One
line per judge and margin: how many sessions it chose within 5 % of the best model on
both inside and edges, and its worst excess.
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from kisscal.camera import Camera
from kisscal.dlt import calibrate_rods, select
from kisscal.rig import Rig
from kisscal.session.inputs import load_config
from kisscal.session.linearise import grid_linearisations
from kisscal.session.params import stage_params
from kisscal.session.routes import RouteInputs
from kisscal.session.routes.trial_bundle import rod_blobs
from tests.session.lens_model_acceptance import volume_errors

Held = dict[str, list[tuple[np.ndarray, np.ndarray]]]  # model -> (ids, errors) per design


def measure(preset: str, seed: int, root: Path) -> tuple[dict, Held, int]:
    """Each model's volume errors and held-out rod markers (ids, 3D errors) by design."""
    config = load_config(root)
    params = stage_params(config)
    lins = grid_linearisations(config, lambda *a: None)
    inputs = RouteInputs(root, config, config.cameras, lins, params, lambda *a: None)
    blobs, rods = rod_blobs(inputs)
    held: Held = {}
    cross = select._cross_validate

    def kept(cameras, fold, p, full):  # the same folds the default's choice runs
        out = cross(cameras, fold, p, full)
        name = next(
            m for m, s in select.MODELS.items() if all(getattr(p, k) == v for k, v in s.items())
        )
        held.setdefault(name, []).append(out[:2])
        return out

    select._cross_validate = kept
    try:
        calibrate_rods(blobs, rods, params.dlt, False)
    finally:
        select._cross_validate = cross
    volume = {}
    for name, switches in select.MODELS.items():
        cal = calibrate_rods(
            blobs, rods, replace(params.dlt, select_model=False, **switches), False
        )
        res = cal.results
        cams = (
            Camera.from_dlt(res[c.id].L, c.id, lins.get(c.id), res[c.id].lens, c.size_px)
            for c in config.cameras
        )
        volume[name] = volume_errors(root, preset, seed, Rig(tuple(cams)))
    return volume, held, max(len(r.points_mm) for r in rods)


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(e**2)))


def _by_rod(ids: np.ndarray, e: np.ndarray, markers: int) -> float:
    rod = ids // markers
    return float(np.sqrt(np.mean([np.mean(e[rod == g] ** 2) for g in np.unique(rod)])))


JUDGES: dict[str, Callable[[list, int], float]] = {
    "rod RMS": lambda h, n: _rms(h[0][1]),
    "staggered RMS": lambda h, n: _rms(h[1][1]),
    "geometric mean": lambda h, n: float(np.sqrt(_rms(h[0][1]) * _rms(h[1][1]))),
    "per-rod RMS": lambda h, n: _by_rod(*h[0], n),
    "rod median": lambda h, n: float(np.median(h[0][1])),
    "staggered median": lambda h, n: float(np.median(h[1][1])),
}


def excess(volume: dict, model: str) -> float:
    """How much worse than the best model ``model`` is (inside or edges, the worse)."""
    return max(
        volume[model][k] / min(v[k] for v in volume.values()) - 1 for k in ("inside", "edges")
    )


def judged(runs: list, judge: str, margin: float) -> dict:
    """One judge's choices on every session and how they fared against the truth."""
    picks, worst = [], []
    for volume, held, markers in runs:
        weighed = {
            m: JUDGES[judge](held[m], markers) * (1 + margin * (select.MODEL_UNKNOWNS[m] - 11))
            for m in held
        }
        picks.append(min(weighed, key=weighed.__getitem__))
        worst.append(excess(volume, picks[-1]))
    line = {"judge": judge, "margin": margin, "within_5pct": sum(w <= 0.05 for w in worst)}
    return {**line, "picks": picks, "worst_pct": round(100 * max(worst), 1)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rigs", nargs="+", help="PRESET:SEED:FOLDER")
    args = parser.parse_args()
    runs = []
    for arg in args.rigs:
        preset, seed, folder = arg.split(":", 2)
        volume, held, markers = measure(preset, int(seed), Path(folder))
        print(json.dumps({"rig": f"{preset}:{seed}", "volume": volume}), flush=True)
        runs.append((volume, held, markers))
    for judge in JUDGES:
        for margin in (0.0, 0.02, 0.05):
            print(json.dumps(judged(runs, judge, margin)))


if __name__ == "__main__":
    main()
