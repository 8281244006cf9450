"""Every identity switch of issue 26's C3D re-tracking, one line each, with its cause (run it):

    python -m tests.io.c3d_switches [cache folder] [file name ...]

For each file (default: every file of :mod:`tests.io.c3d_acceptance` found), the file's
markers are re-tracked from shuffled anonymous points as the acceptance does, and every
switch that the file itself does not make (``relabel`` there) and that does not join
a sample both markers share (:func:`~tests.io.c3d_acceptance.shared_samples`) is listed: the fields
before and after it, the two true markers, the stage that joined the two samples
(``track``: one piece of the tracker; ``blend``: two pieces blended; ``label``: joined
after blending) and a class:

- ``gap``: the two samples are more than one field apart (a wrong re-join across a gap);
- ``occlusion``: the first marker has no sample in the field after (it vanished and the
  track took the other);
- ``close``: the two markers are nearer each other than the first marker's own motion
  misses its constant-acceleration prediction by (the motion model cannot tell them);
- ``fast``: the first marker's acceleration (second difference, mm/field²) is larger
  than half the distance between the markers;
- ``rate``: the marker moves more per field than the markers are apart;
- ``other``: none of these.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from kisscal.errors import KisscalError
from kisscal.io.c3d import read_c3d
from kisscal.tracking import MEASURED, TrackingParams, build_trajectories
from kisscal.tracking.blending import blend_tracks
from kisscal.tracking.params import reconstructed_points
from kisscal.tracking.tracker import track_points
from tests.io.c3d_acceptance import (
    FILES,
    HELD_OUT,
    cache_folder,
    distinct,
    file_relabels,
    find,
    shared_samples,
    shuffled,
    system_fills,
    true_channel,
)


@dataclass(frozen=True)
class Switch:
    before: int
    after: int
    a: int
    b: int
    stage: str
    kind: str
    apart_mm: float
    speed_mm: float
    accel_mm: float
    miss_mm: float


def _piece_of(tracks, n_rows: int):
    """The piece of each input row (measured samples; -1: none)."""
    out = np.full(n_rows, -1)
    m = (tracks.status == MEASURED) & (tracks.point >= 0)
    out[tracks.point[m]] = tracks.track[m]
    return out


def _kind(xyz: np.ndarray, before: int, after: int, a: int, b: int) -> tuple[str, ...]:
    """Class of a switch from marker ``a`` (field ``before``) to ``b`` (``after``) and the
    numbers behind it: distance between a and b, a's speed, acceleration, miss."""
    p = xyz[:, a]
    apart = float(np.linalg.norm(xyz[before, a] - xyz[before, b]))
    if not np.isfinite(apart):
        apart = float(np.linalg.norm(xyz[after, a] - xyz[after, b]))
    lo = max(before - 2, 0)
    speed = float(np.linalg.norm(p[before] - p[before - 1])) if before else np.nan
    accel = float(np.linalg.norm(p[before] - 2 * p[before - 1] + p[lo])) if before > 1 else np.nan
    # How far a's own sample after the switch misses its constant-acceleration prediction.
    ahead = 3 * p[before] - 3 * p[before - 1] + p[lo] if before > 1 else p[before]
    miss = float(np.linalg.norm(p[min(after, len(p) - 1)] - ahead))
    if after - before > 1:
        kind = "gap"
    elif not np.isfinite(p[after]).all():
        kind = "occlusion"
    elif np.isfinite(miss) and apart < miss:
        kind = "close"
    elif np.isfinite(accel) and accel > 0.5 * apart:
        kind = "fast"
    elif np.isfinite(speed) and speed > apart:
        kind = "rate"
    else:
        kind = "other"
    return kind, apart, speed, accel, miss


def switches(xyz: np.ndarray, rate_hz: float, params: TrackingParams | None = None) -> list[Switch]:
    """The switches of one file's re-tracking that the file does not make itself."""
    field, points, channel = shuffled(xyz)
    params = reconstructed_points(params or TrackingParams())
    raw = track_points(field, points, params)
    blended = blend_tracks(raw, params)
    res = build_trajectories(field, points, params, rate_hz=rate_hz)
    tr = res.tracks
    ident = true_channel(tr, field, points, channel)
    raw_piece, blend_piece = _piece_of(raw, len(field)), _piece_of(blended, len(field))
    clean = distinct(xyz)
    fills = system_fills(clean)
    out = []
    for t in range(tr.n_tracks):
        rows = np.flatnonzero((tr.track == t) & (tr.status == MEASURED))
        rows = rows[np.argsort(tr.field[rows])]
        ids, fields, pts = ident[rows], tr.field[rows], tr.point[rows]
        for i in np.flatnonzero(ids[1:] != ids[:-1]):
            f0, f1, a, b = (int(v) for v in (fields[i], fields[i + 1], ids[i], ids[i + 1]))
            args = (np.array([f0]), np.array([f1]), np.array([a]), np.array([b]))
            if a < 0 or b < 0 or file_relabels(clean, *args, fills):
                continue
            if shared_samples(xyz, clean, *args).any():
                continue
            r0, r1 = pts[i], pts[i + 1]
            if raw_piece[r0] == raw_piece[r1]:
                stage = "track"
            elif blend_piece[r0] == blend_piece[r1]:
                stage = "blend"
            else:
                stage = "label"
            kind, *nums = _kind(clean, f0, f1, a, b)
            out.append(Switch(f0, f1, a, b, stage, kind, *nums))
    return out


def main(argv: list[str]) -> None:
    folder = cache_folder(argv[0] if argv else None)
    wanted = set(argv[1:])
    total: dict[str, int] = {}
    for item in FILES + HELD_OUT:
        if wanted and item.name not in wanted:
            continue
        path = find(item.name, folder)
        if path is None:
            continue
        try:
            c3d = read_c3d(path)
        except KisscalError:
            continue
        if not np.isfinite(c3d.xyz_mm).all(axis=2).any():
            continue
        found = switches(c3d.xyz_mm, c3d.rate_hz)
        print(f"{item.name} ({c3d.rate_hz:g} Hz): {len(found)} switches")
        for s in found:
            total[s.kind] = total.get(s.kind, 0) + 1
            print(
                f"  {s.before:5d}->{s.after:<5d} {c3d.labels[s.a]:>10} -> {c3d.labels[s.b]:<10} "
                f"{s.stage:5} {s.kind:9} apart {s.apart_mm:6.1f} speed {s.speed_mm:5.1f} "
                f"accel {s.accel_mm:5.1f} miss {s.miss_mm:5.1f} mm"
            )
    print("classes:", ", ".join(f"{k} {v}" for k, v in sorted(total.items())))


if __name__ == "__main__":
    main(sys.argv[1:])
