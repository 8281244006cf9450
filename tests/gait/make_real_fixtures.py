"""Rebuild fixtures/real/gait/ from the source files (not needed to run the tests):

    python -m tests.gait.make_real_fixtures SOURCE_DIR

``SOURCE_DIR`` holds each source as ``owner+name/path`` (e.g.
``DART-Lab-LLUI+python-gaitalytics/tests/treadmill_events.c3d``), copied from the public
repositories ``_real.TRIALS`` names. Every file is trimmed to the markers the events
need, keeping every frame, the first frame number, the residuals and the EVENT group.
Trials whose events come from force plates get an EVENT group written from the plates'
contacts (the foot whose heel, or toe at foot off, is over the plate).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from tests.gait._real import FIXTURES, TRIALS, RealTrial

THRESHOLD_N = 20.0


def source_path(root: Path, trial: RealTrial) -> Path:
    repo, path = trial.source.split(":", 1)
    return root / repo.replace("/", "+") / path


def plate_events(c3d, heel: dict, toe: dict, rate: float) -> list[tuple[str, str, float]]:
    """(side, label, time s from the first frame) of every plate contact that is a foot's."""
    plates = c3d["parameters"]["FORCE_PLATFORM"]
    corners = plates["CORNERS"]["value"]
    fz_channel = plates["CHANNEL"]["value"][2] - 1
    analog = c3d["data"]["analogs"][0]
    analog_rate = float(c3d["header"]["analogs"]["frame_rate"])
    out = []
    for k, channel in enumerate(fz_channel):
        fz = np.abs(analog[channel] - np.median(analog[channel][:200]))
        loaded = np.flatnonzero(fz > THRESHOLD_N)
        if not len(loaded):
            continue
        lo, hi = corners[:2, :, k].min(axis=1), corners[:2, :, k].max(axis=1)
        for label, i, role in (("Foot Strike", loaded[0], heel), ("Foot Off", loaded[-1], toe)):
            t = i / analog_rate
            for side in ("Left", "Right"):
                xy = role[side.lower()][round(t * rate), :2]
                if np.all(np.isfinite(xy)) and np.all((xy >= lo) & (xy <= hi)):
                    out.append((side, label, t))
    return out


def trim(src: Path, trial: RealTrial, dst: Path) -> None:
    import ezc3d

    c3d = ezc3d.c3d(str(src), extract_forceplat_data=False)
    params = c3d["parameters"]
    labels = list(params["POINT"]["LABELS"]["value"])
    idx = [labels.index(n) for n in trial.markers]
    rate = float(params["POINT"]["RATE"]["value"][0])
    first = int(c3d["header"]["points"]["first_frame"])
    out = ezc3d.c3d()
    out["parameters"]["POINT"]["RATE"]["value"] = [rate]
    out["parameters"]["POINT"]["LABELS"]["value"] = list(trial.markers)
    out["parameters"]["POINT"]["UNITS"]["value"] = list(params["POINT"]["UNITS"]["value"])
    out["data"]["points"] = c3d["data"]["points"][:, idx, :]
    meta = c3d["data"]["meta_points"]
    out["data"]["meta_points"] = {k: meta[k][:, idx, :] for k in ("residuals", "camera_masks")}
    if "force plates" in trial.events_from:
        xyz = c3d["data"]["points"][:3].transpose(2, 1, 0)
        mk = dict(zip(labels, xyz.transpose(1, 0, 2), strict=False))
        heel = {"left": mk[trial.heel[0]], "right": mk[trial.heel[1]]}
        toe = {"left": mk[trial.toe[0]], "right": mk[trial.toe[1]]}
        found = plate_events(c3d, heel, toe, rate)
        contexts = [s for s, _, _ in found]
        names = [e for _, e, _ in found]
        times = np.array([[0.0] * len(found), [t + first / rate for _, _, t in found]])
    else:
        event = params["EVENT"]
        contexts = list(event["CONTEXTS"]["value"])
        names = list(event["LABELS"]["value"])
        times = np.asarray(event["TIMES"]["value"], dtype=float)
    out.add_parameter("EVENT", "USED", len(names))
    out.add_parameter("EVENT", "CONTEXTS", contexts)
    out.add_parameter("EVENT", "LABELS", names)
    out.add_parameter("EVENT", "TIMES", times)
    out.add_parameter("EVENT", "DESCRIPTIONS", [trial.events_from[:60]] * len(names))
    out["header"]["points"]["first_frame"] = first
    out.write(str(dst))


def main(argv: list[str]) -> None:
    root = Path(argv[1])
    FIXTURES.mkdir(parents=True, exist_ok=True)
    for trial in TRIALS:
        trim(source_path(root, trial), trial, trial.path)
        print(f"{trial.name}: {trial.path.stat().st_size / 1024:.0f} kB")


if __name__ == "__main__":
    main(sys.argv)
