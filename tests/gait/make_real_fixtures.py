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

from tests.gait._real import (
    FIXTURES,
    PLATE_GROUP,
    TRIALS,
    ZOO,
    RealTrial,
    mm_per_unit,
    point_labels,
    z_up,
)

THRESHOLD_N = 20.0
#: A plate loaded for less than this is not a foot's stance.
MIN_CONTACT_S = 0.4


def source_path(root: Path, trial: RealTrial) -> Path:
    repo, path = trial.source.split(":", 1)
    return root / repo.replace("/", "+") / path


def plate_events(
    c3d, heel: dict, toe: dict, rate: float, up: str = "z", mm: float = 1.0
) -> list[tuple[str, str, float]]:
    """(context, label, time s from the first frame) of every contact a plate sees in
    full, as a foot's: the foot whose heel is over the plate at the start (the slower
    one if both are) gets the start, the foot whose toe is
    over it at the end gets the end; a contact whose ends go to different feet is
    dropped. The unloaded level is the most common value of the plate's vertical force
    (a treadmill's belt is loaded more than half the time, so its median is not)."""
    plates = c3d["parameters"]["FORCE_PLATFORM"]
    corners = np.asarray(plates["CORNERS"]["value"]).transpose(1, 2, 0) * mm  # POINT units
    corners = z_up(corners, up).transpose(2, 0, 1)
    fz_channel = np.atleast_2d(plates["CHANNEL"]["value"])[2] - 1
    analog = c3d["data"]["analogs"][0]
    analog_rate = float(c3d["header"]["analogs"]["frame_rate"])
    out = []
    for k, channel in enumerate(fz_channel):
        fz = analog[channel]
        if not np.ptp(fz) > THRESHOLD_N:
            continue  # an unused plate
        counts, bins = np.histogram(fz, bins=np.arange(fz.min(), fz.max() + 5.0, 5.0))
        loaded = np.abs(fz - bins[np.argmax(counts)] - 2.5) > THRESHOLD_N
        box = corners[:2, :, k].min(axis=1), corners[:2, :, k].max(axis=1)
        for start, end in _contacts(loaded, analog_rate):
            feet = {
                label: _foot_over(role, box, t, rate)
                for label, role, t in (("Foot Strike", heel, start), ("Foot Off", toe, end))
                if t is not None
            }
            if len(set(feet.values()) - {None}) != 1:
                continue  # no foot, or two feet: not one foot's stance
            for label, side in feet.items():
                if side is not None:
                    out.append((side, label, start if label == "Foot Strike" else end))
    return _first_strikes(sorted(out, key=lambda e: e[2]))


def _first_strikes(events: list[tuple[str, str, float]]) -> list[tuple[str, str, float]]:
    """Drop a foot strike that follows the same foot's strike by less than 0.5 s: the
    foot rolling onto the next plate in the same stance."""
    out, last = [], {}
    for side, label, t in events:
        if label == "Foot Strike":
            if t - last.get(side, -np.inf) < 0.5:
                continue
            last[side] = t
        out.append((side, label, t))
    return out


def _foot_over(role: dict, box, t: float, rate: float) -> str | None:
    """The side whose marker is over the plate at ``t``; if both are, the slower one
    (a foot landing or pushing off, not the other swinging over the plate)."""
    n = next(iter(role.values())).shape[0]
    frame = round(t * rate)
    if not 1 <= frame < n - 1:
        return None
    over = {}
    for side in ("Left", "Right"):
        track = role[side.lower()]
        p = track[frame]
        if np.all(np.isfinite(p)) and np.all((p[:2] >= box[0]) & (p[:2] <= box[1])):
            over[side] = np.linalg.norm(track[frame + 1] - track[frame - 1])
    return min(over, key=over.get) if over else None


def _contacts(loaded: np.ndarray, rate: float) -> list[tuple[float | None, float | None]]:
    """(start, end) s of the plate's contacts: loaded runs of 0.15 to 1.5 s (bridging
    dropouts under 20 ms). An end cut by the recording, or without 50 ms unloaded next
    to it, is None; so is the end of a contact shorter than MIN_CONTACT_S (a foot that
    rolled off the plate onto the floor, not a foot off)."""
    from kisscal._shared import true_runs

    merged: list[list[int]] = []
    for a, b in zip(*true_runs(loaded), strict=True):
        if merged and a - merged[-1][1] < 0.02 * rate:
            merged[-1][1] = b
        else:
            merged.append([a, b])
    out = []
    for j, (a, b) in enumerate(merged):
        if not 0.15 * rate <= b - a <= 1.5 * rate:
            continue
        before = a - (merged[j - 1][1] if j else 0)
        after = (merged[j + 1][0] if j + 1 < len(merged) else len(loaded)) - b
        start = a / rate if a > 0 and before >= 0.05 * rate else None
        whole = b < len(loaded) and after >= 0.05 * rate and b - a >= MIN_CONTACT_S * rate
        out.append((start, (b - 1) / rate if whole else None))
    return out


def trim(src: Path, trial: RealTrial, dst: Path) -> None:
    import ezc3d

    c3d = ezc3d.c3d(str(src), extract_forceplat_data=False)
    params = c3d["parameters"]
    labels = point_labels(params)
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
    xyz = c3d["data"]["points"][:3].transpose(2, 1, 0).copy()
    xyz[np.all(xyz == 0.0, axis=2)] = np.nan
    mm = mm_per_unit(params)
    xyz = z_up(xyz * mm, trial.up)
    mk: dict[str, np.ndarray] = {}
    for label, track in zip(labels, xyz.transpose(1, 0, 2), strict=True):
        mk.setdefault(label, track)  # a label given twice: the first, as labels.index
    heel = {"left": mk[trial.heel[0]], "right": mk[trial.heel[1]]}
    toe = {"left": mk[trial.toe[0]], "right": mk[trial.toe[1]]}
    has_plates = "FORCE_PLATFORM" in params
    plates = plate_events(c3d, heel, toe, rate, trial.up, mm) if has_plates else []
    plate_times = np.array([[0.0] * len(plates), [t + first / rate for _, _, t in plates]])
    if "force plates" in trial.events_from:
        contexts = [s for s, _, _ in plates]
        names = [e for _, e, _ in plates]
        times = plate_times
    else:
        event = params["EVENT"]
        contexts = list(event["CONTEXTS"]["value"])
        names = list(event["LABELS"]["value"])
        times = np.asarray(event["TIMES"]["value"], dtype=float)
    if not names:  # ezc3d writes no empty list: one blank event, read as none
        contexts, names, times = [""], [""], np.zeros((2, 1))
    out.add_parameter("EVENT", "USED", len(names))
    out.add_parameter("EVENT", "CONTEXTS", contexts)
    out.add_parameter("EVENT", "LABELS", names)
    out.add_parameter("EVENT", "TIMES", times)
    out.add_parameter("EVENT", "DESCRIPTIONS", [trial.events_from[:60]] * len(names))
    # The plates' contacts, for scoring against force plates alone (a group of its own:
    # lab software reads only EVENT).
    out.add_parameter(PLATE_GROUP, "CONTEXTS", [s for s, _, _ in plates] or [""])
    out.add_parameter(PLATE_GROUP, "LABELS", [e for _, e, _ in plates] or [""])
    out.add_parameter(PLATE_GROUP, "TIMES", plate_times if plates else np.zeros((2, 1)))
    out["header"]["points"]["first_frame"] = first
    out.write(str(dst))


def main(argv: list[str]) -> None:
    root = Path(argv[1])
    FIXTURES.mkdir(parents=True, exist_ok=True)
    for trial in TRIALS + ZOO:
        trim(source_path(root, trial), trial, trial.path)
        print(f"{trial.name}: {trial.path.stat().st_size / 1024:.0f} kB")


if __name__ == "__main__":
    main(sys.argv)
