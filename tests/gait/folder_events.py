"""Gait events of every C3D file in a folder against the events its lab marked (run it):

    python -m tests.gait.folder_events FOLDER [FOLDER ...] [--worst N]

Not needed by the tests (the files are not committed): a check of kisscal's foot strikes
and foot offs on walking trials as labs keep them (Plug-in Gait names, with or without a
``subject:`` prefix; the ankle stands in for a heel marker with no data). Per trial and
pooled: the mean signed error (bias), the mean absolute error, the worst error (signed)
and the marked events missed, of kisscal and of Zeni et al. (2008)'s coordinate rule on
the same markers (:func:`tests.gait.real_events.coordinate_events`). Pooled again over
the marked events a force plate confirms (one of its contacts, :func:`plate_events`,
within :data:`ON_PLATE_S`) and over the others (marked by eye or by the lab's software).
The biomechZoo fixtures (``fixtures/real/gait/zoo_*``) are a folder it reads too.
``--worst N`` lists the N largest errors of each column (missed events first) with the
file, side and marked time, and whether a plate confirms the marked event. ``--plates``
scores against the force plates' contacts instead of the EVENT group (a fixture's
``PLATE_EVENT`` group, else the plates of the file: walks that mark no events). Last,
where the spread of each column comes from (:func:`spread`): offsets between trials, or
scatter within a trial or within one foot of a trial.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from kisscal.gait import GaitMarkers, detect_events, heel_from_ankle
from kisscal.gait.table import EVENTS
from tests.gait._real import PLATE_GROUP, mm_per_unit, read
from tests.gait.make_real_fixtures import plate_events
from tests.gait.real_events import EDGE_S, MATCH_S, Errors, coordinate_events, score

#: A marked event with a plate's contact of its side and kind this close (s) is the plate's.
ON_PLATE_S = 0.02
_ROLES = {"pelvis": ("LASI", "RASI", "LPSI", "RPSI", "SACR"), "heel": ("LHEE", "RHEE")}
_ROLES |= {"ankle": ("LANK", "RANK"), "toe": ("LTOE", "RTOE")}


def gait_trial(markers: dict[str, np.ndarray], rate: float) -> GaitMarkers | None:
    """The trial's gait markers by their Plug-in Gait names (None if some are missing)."""
    found = {}
    for name, track in markers.items():
        key = name.split(":")[-1].strip().upper()
        if np.isfinite(track).all(axis=1).mean() > 0.5 and key not in found:
            found[key] = track
    role = {r: [found.get(n) for n in names] for r, names in _ROLES.items()}
    if any(x is None for x in role["toe"]) or not any(x is not None for x in role["pelvis"]):
        return None
    toe = dict(zip(("left", "right"), role["toe"], strict=True))
    heel, stand_in = {}, []
    for side, h, a in zip(("left", "right"), role["heel"], role["ankle"], strict=True):
        if h is None and a is None:
            return None
        heel[side] = h if h is not None else heel_from_ankle(a, toe[side])
        stand_in += [side] if h is None else []
    pelvis = tuple(p for p in role["pelvis"] if p is not None)
    return GaitMarkers(pelvis, heel, toe, rate, {}, tuple(stand_in))


def plates(path: Path, gm: GaitMarkers) -> dict[tuple[str, str], np.ndarray]:
    """The force plates' contacts of the file, as its foot strikes and foot offs."""
    import ezc3d

    c3d = ezc3d.c3d(str(path))
    params = c3d["parameters"]
    if "FORCE_PLATFORM" not in params or "CORNERS" not in params["FORCE_PLATFORM"]:
        return {}
    mm = mm_per_unit(params)
    out: dict[tuple[str, str], list[float]] = {}
    try:
        contacts = plate_events(c3d, gm.heel, gm.toe, gm.rate_hz, "z", mm)
    except (IndexError, KeyError, ValueError):
        return {}
    for side, label, t in contacts:
        out.setdefault((side.lower(), label.lower().replace(" ", "_")), []).append(t)
    return {k: np.asarray(v) for k, v in out.items()}


def _cells(err: Errors) -> str:
    out = []
    for e in EVENTS:
        x = 1000 * np.asarray(err.errors[e])
        bias, worst = (x.mean(), x[np.argmax(np.abs(x))]) if len(x) else (np.nan, np.nan)
        out.append(f"{bias:+6.1f} {err.mean_ms(e):5.1f} {worst:+6.1f} {err.missed[e]:2d}")
    return "  ".join(out)


def table(paths: list[Path], worst: int = 0, by_plates: bool = False) -> list[str]:
    """One line per file with marked foot strikes and foot offs (the plates' contacts if
    ``by_plates``), then the pooled ones."""
    head = "bias  mean  worst mi"
    lines = [
        f"{'trial':<30} {'n':>3}  {'kisscal FS':^20}  {'kisscal FO':^20}"
        f"  {'Zeni FS':^20}  {'Zeni FO':^20}",
        f"{'':<30} {'':>3}  {head:^20}  {head:^20}  {head:^20}  {head:^20}",
    ]
    pooled = {k: (Errors(), Errors()) for k in ("all", "on a plate", "not on a plate")}
    rows: list[tuple] = []  # column, |error| (inf: missed), line, trial, side, error
    for path in paths:
        try:
            markers, rate, _, marked = read(path, PLATE_GROUP if by_plates else "EVENT")
        except (OSError, RuntimeError, ValueError, IndexError, ZeroDivisionError) as e:
            lines.append(f"{path.stem[:30]:<30} unreadable: {str(e).splitlines()[0][:60]}")
            continue
        gm = gait_trial(markers, rate) if marked or by_plates else None
        contacts = marked if by_plates and marked else plates(path, gm) if gm is not None else {}
        marked = contacts if by_plates else marked
        if gm is None or not marked:
            continue
        on = {k: np.asarray([t for t in v if _near(contacts.get(k), t)]) for k, v in marked.items()}
        off = {k: np.setdiff1d(v, on[k]) for k, v in marked.items()}
        duration = gm.n_fields / rate
        found = detect_events(gm), coordinate_events(gm)
        for key, events in (("all", marked), ("on a plate", on), ("not on a plate", off)):
            for pool, detection in zip(pooled[key], found, strict=True):
                pool.add(score(detection, events, duration))
        ours, zeni = (score(d, marked, duration) for d in found)
        n = sum(len(v) for v in marked.values())
        name = path.stem + ("*" if gm.heel_from_ankle else "")
        lines.append(f"{name[:30]:<30} {n:3d}  {_cells(ours)}  {_cells(zeni)}")
        for method, detection in zip(("kisscal", "Zeni"), found, strict=True):
            rows += _event_rows(name, method, detection, marked, on, duration)
    for key, (ours, zeni) in pooled.items():
        n = sum(len(v) for v in ours.errors.values()) + sum(ours.missed.values())
        if n:  # no plate in the files: no plate lines
            lines.append(f"{key:<30} {n:3d}  {_cells(ours)}  {_cells(zeni)}")
    lines.append("ms; bias: mean signed error (detected - marked); mean: mean absolute error;")
    lines.append("worst: the largest in magnitude, signed; mi: marked events missed;")
    lines.append("* the ankle stands in for the heel")
    for column in (f"{m} {e}" for m in ("kisscal", "Zeni") for e in EVENTS):
        found = [(r[3], r[4], r[5]) for r in rows if r[0] == column and np.isfinite(r[1])]
        if len(found) > 1:
            sd = ", ".join(f"{1000 * x:.1f}" for x in spread(found))
            n = f"{len(found)}, {len({x[0] for x in found})}, {len({x[:2] for x in found})}"
            lines.append(
                f"spread, {column} ({n} events, trials, feet): SD {sd} ms"
                " (all; trial means; within a trial; within a foot)"
            )
    for column in (f"{m} {e}" for m in ("kisscal", "Zeni") for e in EVENTS if worst):
        lines.append(f"worst {worst}, {column}:")
        ranked = sorted((r for r in rows if r[0] == column), key=lambda r: -r[1])
        lines += [r[2] for r in ranked[:worst]]
    return lines


def spread(errors: list[tuple[str, str, float]]) -> tuple[float, float, float, float]:
    """Where the scatter of signed errors comes from: the SD of the ``(trial, side,
    error)`` errors, of their trials' means (offsets between trials: lab, subject,
    marker placement), and the pooled SD about their trial's mean and about their
    trial's side's mean (scatter within a trial, within one foot; NaN where no group
    holds two errors)."""
    e = np.array([x[2] for x in errors])
    out = [float(e.std())]
    for labels in ([x[0] for x in errors], [x[:2] for x in errors]):
        groups = [e[[i for i, x in enumerate(labels) if x == g]] for g in dict.fromkeys(labels)]
        if len(out) == 1:
            out.append(float(np.std([v.mean() for v in groups])))
        dof = len(e) - len(groups)  # a group's mean takes one
        sq = sum(float(np.sum((v - v.mean()) ** 2)) for v in groups)
        out.append(float(np.sqrt(sq / dof)) if dof else float("nan"))
    return out[0], out[1], out[2], out[3]


def _event_rows(name, method, detection, marked, on, duration) -> list[tuple]:
    """(column, |error| or inf when missed, line, trial, side, error) for every marked
    event scored."""
    out = []
    for (side, event), times in marked.items():
        d = detection.times(side, event)
        for t in times:
            err = d[np.argmin(np.abs(d - t))] - t if len(d) else np.inf
            if abs(err) > MATCH_S and not EDGE_S[0] <= t <= duration - EDGE_S[1]:
                continue  # a stride cut by the trial's end: not scored
            cell = "missed" if abs(err) > MATCH_S else f"{1000 * err:+7.1f} ms"
            plate = " plate" if _near(on.get((side, event)), t) else ""
            line = f"  {name[:30]:<30} {side:<5} {t:7.3f} s  {cell}{plate}"
            size = abs(err) if abs(err) <= MATCH_S else np.inf
            out.append((f"{method} {event}", size, line, name, side, err))
    return out


def _near(times: np.ndarray | None, t: float) -> bool:
    return times is not None and bool(np.any(np.abs(times - t) <= ON_PLATE_S))


def main(argv: list[str]) -> None:
    folders, worst = list(argv[1:]), 0
    by_plates = "--plates" in folders
    folders = [f for f in folders if f != "--plates"]
    if "--worst" in folders:
        k = folders.index("--worst")
        worst = int(folders[k + 1])
        del folders[k : k + 2]
    paths = sorted(p for d in folders for p in Path(d).iterdir() if p.suffix.lower() == ".c3d")
    print("\n".join(table(paths, worst, by_plates)))


if __name__ == "__main__":
    main(sys.argv)
