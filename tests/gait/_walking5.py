"""walking5.c3d: its labelled markers, and true foot contacts from its two force plates."""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources

import numpy as np

from kisscal.gait import GaitMarkers, gait_markers
from kisscal.io.c3d import read_c3d_points
from kisscal.markersets import marker_set

#: Vertical force (N, above the unloaded plate) taken as contact.
THRESHOLD_N = 20.0


@dataclass
class PlateEvent:
    side: str
    event: str
    time_s: float
    plate: int


def path():
    return resources.files("kisscal.data") / "walking5.c3d"


def load(step: int = 1, offset: int = 0) -> tuple[GaitMarkers, float]:
    """The trial's heel, toe and pelvis markers (every ``step``-th frame from ``offset``)
    and its full rate."""
    labels, xyz, rate = read_c3d_points(path())
    markers = dict(zip(labels, xyz[offset::step].transpose(1, 0, 2), strict=True))
    return gait_markers(markers, rate / step, marker_set("plug-in-gait-full")), rate


def plate_events() -> list[PlateEvent]:
    """Foot strikes and foot offs the force plates see, with the foot they belong to.

    A plate's contact is a foot's only if that foot's marker is over the plate at that
    instant: the heel at foot strike, the toe at foot off (walking5's left heel lands
    off plate 1, so that plate's first load is the forefoot, not a foot strike).
    """
    import ezc3d

    c3d = ezc3d.c3d(str(path()))
    gm, rate = load()
    plates = c3d["parameters"]["FORCE_PLATFORM"]
    corners = plates["CORNERS"]["value"]  # (3, 4, plates)
    fz_channel = plates["CHANNEL"]["value"][2] - 1  # 1-based analog channel of Fz, per plate
    analog = c3d["data"]["analogs"][0]
    analog_rate = float(c3d["header"]["analogs"]["frame_rate"])
    out = []
    for k, channel in enumerate(fz_channel):
        fz = np.abs(analog[channel] - np.median(analog[channel][:200]))  # unloaded at the start
        loaded = np.flatnonzero(fz > THRESHOLD_N)
        if not len(loaded):
            continue
        lo, hi = corners[:2, :, k].min(axis=1), corners[:2, :, k].max(axis=1)
        for event, i, role in (("foot_strike", loaded[0], "heel"), ("foot_off", loaded[-1], "toe")):
            t = i / analog_rate
            frame = round(t * rate)
            for side in ("left", "right"):
                xy = getattr(gm, role)[side][frame, :2]
                if np.all(np.isfinite(xy)) and np.all((xy >= lo) & (xy <= hi)):
                    out.append(PlateEvent(side, event, t, k + 1))
    return out
