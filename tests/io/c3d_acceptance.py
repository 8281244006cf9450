"""Issue 26's regression set of real C3D files (run it):

    python -m tests.io.c3d_acceptance [cache folder]

Each file of :data:`FILES` found in ``fixtures/real/c3d/`` (committed, small) or in the
cache folder (default ``$KISSCAL_C3D_CACHE`` or ``../shared/data/real/c3d``; larger
files) is read with :func:`kisscal.io.c3d.read_c3d` (markers only) and:

- re-tracked from shuffled anonymous points: every frame's valid samples in random order,
  no labels, tracked with default parameters; a sample's true marker is the channel it
  came from (exact coordinates). Reported: identity switches (a change of true marker
  along one trajectory), of them those where the file itself renames the marker
  (``relabel``: see :func:`file_relabels`; a channel's straight-line gap fill by the
  writing system is no sample of the marker, :func:`system_fills`), coverage (the
  file's valid samples that come out as measured samples of a trajectory), trajectories;
- when the file's markers belong to a shipped marker set (``SET`` below), labelled from
  the set alone as the system wrote them (every channel, in the file's order, labels
  dropped): names right / named / markers of the set in the file, and names forced on
  the wrong marker (``wrong``; flagged ones counted apart), and right names that are
  flagged (``(flag)``); a full-body file also without its arm markers, and the files of
  :data:`TURNED` also with the lab turned (another axis up: the vertical must come from
  the data).

Files, their systems, sources and licences: ``fixtures/real/c3d/README.md``.
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kisscal.errors import KisscalError
from kisscal.io.c3d import read_c3d
from kisscal.markersets import marker_set
from kisscal.tracking import MEASURED, TrackingParams, build_trajectories
from kisscal.tracking.params import reconstructed_points

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "real" / "c3d"
WALKING5 = Path(__file__).resolve().parents[2] / "kisscal" / "data" / "walking5.c3d"


@dataclass(frozen=True)
class RealFile:
    name: str
    system: str
    marker_set: str | None = None  # a shipped set the file's markers belong to


#: The regression set: file name (in the fixtures or the cache folder) and system.
FILES = (
    RealFile("walking5.c3d", "Vicon (Nexus), 250 Hz", "plug-in-gait-full"),
    RealFile("walk.c3d", "Vicon (Nexus), 100 Hz, with model outputs", "plug-in-gait-full"),
    RealFile("pc_real.c3d", "Vicon 370 (AMASS), 50 Hz, Intel"),
    RealFile("sgi_int.c3d", "Vicon 370 (AMASS), 50 Hz, SGI/MIPS integer"),
    RealFile("dec_real.c3d", "Vicon 370 (AMASS), 50 Hz, DEC"),
    RealFile("Eb015pr.c3d", "ADTech (AMASS), 50 Hz"),
    RealFile("Qualisys.c3d", "Qualisys (QTM), 200 Hz"),
    RealFile("FP_Type3.c3d", "Qualisys (QTM), 250 Hz, 2 frames"),
    RealFile("duplicate_labels.c3d", "Qualisys (QTM), 100 Hz"),
    RealFile("BTS.c3d", "BTS, 100 Hz"),
    RealFile("kinematics_tennis_serve.c3d", "OptiTrack (Motive), 50 Hz", "plug-in-gait-full"),
    RealFile("kinematics_basket_sprint.c3d", "OptiTrack (Motive), 120 Hz"),
    RealFile("kinematics_racing_propulsion.c3d", "Kinetics Toolkit racing, 70 Hz"),
)

_PIG = "plug-in-gait-full"
#: Held out: C3D.org sample files first read after the set above was built (issue 26's
#: check on files not seen), run blind, then kept as a regression set. Sources: the
#: README beside the fixtures (cache: ``c3dio/`` below the cache folder, the c3dio
#: repository's ``tests/c3d_org_samples/`` as it is).
HELD_OUT = (
    RealFile("codamotion_gaitwands_19970212.c3d", "Codamotion, 200 Hz"),
    RealFile("Gait with EMG.c3d", "Innovative Sports Training, 60 Hz", _PIG),
    RealFile("Sample_Jump2.c3d", "Motion Analysis (Cortex), 120 Hz, jump", _PIG),
    RealFile("test1.c3d", "NexGen Ergonomics, 128 Hz, Y up", _PIG),
    RealFile("pyCGM2 lower limb CGM24 Walking01.c3d", "Vicon (Nexus), 100 Hz", _PIG),
    RealFile("gait-pig-nz.c3d", "Vicon 370, 120 Hz", _PIG),
    RealFile("gait-pig.c3d", "Vicon 370, 50 Hz, DEC", _PIG),
    RealFile("gait-raw.c3d", "Vicon 370, 50 Hz, DEC", _PIG),
    RealFile("sub_labels.c3d", "Vicon 370 (Workstation), 60 Hz, DEC", _PIG),
    RealFile("newwalk.c3d", "Motion Analysis (EVaRT), 60 Hz, DEC", _PIG),
    RealFile("16bitanalog.c3d", "(no valid point: every sample 0 0 0)"),
    RealFile("PlugInC3D.c3d", "Vicon Workstation 4.4, 60 Hz, DEC", _PIG),
    RealFile("TYPE-3.c3d", "AMTI type-3 plates sample, 60 Hz, DEC", _PIG),
    RealFile("2198928.c3d", "Vicon, 60 Hz, DEC", _PIG),
    RealFile("evart.c3d", "Motion Analysis (EVaRT), 60 Hz, DEC, 17 analog/frame", _PIG),
    RealFile("Dance1.c3d", "Phoenix Technologies, 65 Hz, Y up"),
    RealFile("golfswing1.c3d", "Phoenix Technologies, 107.5 Hz, Y up"),
    RealFile("golfswing.c3d", "Phoenix Technologies, float ANALOG:OFFSET"),
    RealFile("sample14.c3d", "Vicon, 50 Hz, DEC", _PIG),
    RealFile("128analogchannels.c3d", "Vicon, 160 Hz"),
    RealFile("sample21.c3d", "Motion Analysis (EVaRT), 60 Hz, DEC"),
    RealFile("Vicon_analysis.c3d", "Vicon, 120 Hz", _PIG),
    RealFile("MotionMonitorC3D.c3d", "The MotionMonitor, 140 Hz, blank labels"),
    RealFile("analogfpscale03.c3d", "Vicon, 120 Hz", _PIG),
    RealFile("Capture0002.c3d", "Qualisys, 240 Hz"),
    RealFile("Walking_Hybrid_1_1.c3d", "Qualisys, 240 Hz"),
    RealFile("Walking_Hybrid_2.c3d", "Qualisys, 240 Hz, 73 points"),
    RealFile("kyowadengyo.c3d", "Kyowa Dengyo, 60 Hz, DEC, POINT:USED wrong"),
    RealFile("dynamic.C3D", "BTS (Biomech 2.5), 100 Hz, no ANALOG parameters"),
    RealFile("marche281.c3d", "Biogesta, 240 Hz"),
    RealFile("admarche2.c3d", "Biogesta, 50 Hz"),
    RealFile("vicon_zerowire.c3d", "Vicon (Nexus), 100 Hz", _PIG),
    RealFile("bigparlove.c3d", "Vicon (Nexus), 200 Hz, 105 markers"),
    RealFile("ART-Human_real.c3d", "A.R.T., 60 Hz"),
    RealFile("golf.c3d", "SIMI, 200 Hz, every residual -1"),
    RealFile("phasespace_sample.c3d", "PhaseSpace, 30 Hz, no parameters"),
    RealFile("FP1.C3D", "Peak Performance, 60 Hz, units 'mete'"),
    RealFile("MACsample.c3d", "Motion Analysis (early), SGI"),
    RealFile("bad_parameter_section.c3d", "corrupt parameter section"),
    RealFile("BKINtechnologies.c3d", "BKIN Dexterit-E, 1000 Hz, 2 points"),
    RealFile("Facial-Sing.c3d", "NaturalPoint (ARENA), no ANALOG group"),
)


def cache_folder(given: str | None = None) -> Path:
    default = Path(__file__).resolve().parents[3] / "shared" / "data" / "real" / "c3d"
    return Path(given or os.environ.get("KISSCAL_C3D_CACHE") or default)


def find(name: str, cache: Path) -> Path | None:
    if name == "walking5.c3d" and WALKING5.is_file():
        return WALKING5
    for folder in (FIXTURES, cache):
        hits = sorted(folder.rglob(name)) if folder.is_dir() else []
        if hits:
            return hits[0]
    return None


#: Two samples of one frame closer than this are one marker: markers are at least about a
#: diameter (6 mm and up) apart. In the regression set, the closest two channels of one
#: frame are 19.6 mm apart except for one pair (tennis serve, LWRA on LWRB, 1.0 mm).
SAME_MARKER_MM = 5.0


def distinct(xyz: np.ndarray) -> np.ndarray:
    """``xyz`` with a sample that repeats an earlier channel's in its frame (within
    :data:`SAME_MARKER_MM`) made invalid (Vicon's Plug-in Gait writes segment points that
    coincide, e.g. RFOO and RTOP; the tennis serve's LWRA jumps 102 mm onto LWRB, 1.0 mm
    from it, for one frame and back): one point in space is one sample, kept under the name
    whose path it continues (the smaller step from the previous frame)."""
    out = xyz.copy()
    n = xyz.shape[1]
    # How far each channel's sample moved from its previous frame's (inf: no previous).
    step = np.full(xyz.shape[:2], np.inf)
    step[1:] = np.linalg.norm(xyz[1:] - xyz[:-1], axis=2)
    step[~np.isfinite(step)] = np.inf
    for j in range(1, n):
        d = np.linalg.norm(out[:, :j] - out[:, j : j + 1], axis=2)
        same = np.flatnonzero((d < SAME_MARKER_MM).any(axis=1))
        i = np.argmin(np.where(np.isfinite(d[same]), d[same], np.inf), axis=1)
        # The sample is the marker's whose path it continues; the other name is dropped.
        keep_j = step[same, j] < step[same, i]
        out[same[~keep_j], j] = np.nan
        out[same[keep_j], i[keep_j]] = np.nan
    return out


def shared_samples(
    xyz: np.ndarray,
    clean: np.ndarray,
    before: np.ndarray,
    after: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
) -> np.ndarray:
    """Which changes from channel ``a`` (field ``before``) to ``b`` (``after``) join a
    sample that is both markers' (:func:`distinct` kept it under one name and dropped the
    other, within :data:`SAME_MARKER_MM`): ``b``'s own sample at ``before`` dropped as
    the sample taken, or ``a``'s at ``after``. The truth does not say whose that one point
    is (two Codamotion sacral wand markers 3-5 mm apart merge in 44 fields), so following
    it under either name is no switch. ``xyz`` the file's samples, ``clean`` after
    :func:`distinct`."""

    def merged(f: np.ndarray, kept: np.ndarray, gone: np.ndarray) -> np.ndarray:
        d = np.linalg.norm(xyz[f, gone] - xyz[f, kept], axis=-1)
        return ~np.isfinite(clean[f, gone, 0]) & (d < SAME_MARKER_MM)

    known = (a >= 0) & (b >= 0)
    return known & (merged(before, a, b) | merged(after, b, a))


def shuffled(xyz: np.ndarray, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every frame's distinct valid samples in random order: (field, points, channel)."""
    rng = np.random.default_rng(seed)
    xyz = distinct(xyz)
    f_idx, m_idx = np.nonzero(np.isfinite(xyz).all(axis=2))
    order = rng.permutation(f_idx.size)
    f_idx, m_idx = f_idx[order], m_idx[order]
    order = np.argsort(f_idx, kind="stable")
    return f_idx[order], xyz[f_idx[order], m_idx[order]], m_idx[order]


def true_channel(tracks, field: np.ndarray, points: np.ndarray, channel: np.ndarray) -> np.ndarray:
    """The file channel of each measured output sample (-1: not a sample of the file)."""
    key = {
        (int(f), *np.round(p, 4).tolist()): int(c)
        for f, p, c in zip(field, points, channel, strict=True)
    }
    out = np.full(len(tracks.field), -1)
    for i in np.flatnonzero(tracks.status == MEASURED):
        out[i] = key.get((int(tracks.field[i]), *np.round(tracks.xyz_mm[i], 4).tolist()), -1)
    return out


@dataclass(frozen=True)
class Retrack:
    markers: int
    frames: int
    valid: int
    trajectories: int
    switches: int
    relabels: int
    coverage: float
    seconds: float


#: A sample within this distance (mm) of the midpoint of its channel's neighbours in the
#: frames before and after lies on their straight line to the storage's rounding: the
#: writing system's linear gap fill, not a measurement. In the regression set, moving
#: measured samples are at least 0.005 mm off that midpoint; the tennis serve (Motive)
#: holds 77 samples at 0.000 (e.g. RFRM in frames 190-192 and 196, where the marker's own
#: reconstruction is written under RELB and RUPA).
FILL_MM = 1e-3
#: Slower than this (mm/frame), a channel may repeat a straight line by standing still.
FILL_MOVING_MM = 1.0


def system_fills(xyz: np.ndarray) -> np.ndarray:
    """(frames, channels) True where the file's sample is the system's linear gap fill
    (:data:`FILL_MM`): on the straight line between the channel's samples of the frames
    before and after, while moving."""
    out = np.zeros(xyz.shape[:2], dtype=bool)
    if xyz.shape[0] < 3:
        return out
    with np.errstate(invalid="ignore"):
        d2 = np.linalg.norm(xyz[2:] - 2.0 * xyz[1:-1] + xyz[:-2], axis=2)
        step = np.linalg.norm(xyz[2:] - xyz[1:-1], axis=2)
        out[1:-1] = (d2 < FILL_MM) & (step > FILL_MOVING_MM)
    return out


def file_relabels(
    xyz: np.ndarray,
    before: np.ndarray,
    after: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    fills: np.ndarray | None = None,
) -> int:
    """How many switches from channel ``a`` (field ``before``) to ``b`` (field ``after``)
    the file makes itself: the name ``b`` takes up ``a``'s path and the name ``a`` leaves
    it. ``b``'s sample at ``after`` lies nearer to ``a``'s constant-velocity extrapolation
    than half the usual distance between the two channels, and ``b`` either has no sample
    at ``before`` or its own sample there is farther than ``a``'s; ``a`` has no sample at
    ``after``, or one no nearer to its extrapolation than half that distance (one marker
    under two names: two markers cannot trade places across a frame while staying apart).
    ``a``'s path comes from ``b``'s sample of the field before when that is nearer than
    ``a``'s own: the file gives back two names it swapped for one field.
    ``a``'s sample at ``after`` that is the system's own linear gap fill (``fills``,
    :func:`system_fills`) is no sample of the marker: the system wrote the marker's
    measurement under ``b`` and filled ``a`` by a straight line. A tracker that follows
    the marker must count these switches. Also counted: one cubic through ``a``'s samples
    before and ``b``'s after fits under half as far as through ``a``'s own
    (:func:`_rejoins`)."""
    own = np.linalg.norm(xyz[after, b] - xyz[before, b], axis=1)
    cross = np.linalg.norm(xyz[after, b] - xyz[before, a], axis=1)
    taken = ~np.isfinite(own) | (own > cross)
    # a's path into ``before``: from a's or b's sample of the field before, the nearer (a
    # file that swaps two names for one field gives them back: OptiTrack's foot markers
    # 5 and 3, 96 mm apart, in frame 1952 of sample_OptiTrack_walking).
    prev = np.maximum(before - 1, 0)
    steps = xyz[before, a][None] - np.stack([xyz[prev, a], xyz[prev, b]])
    own_way = ~(np.linalg.norm(steps[1], axis=1) < np.linalg.norm(steps[0], axis=1))
    step = np.where(own_way[:, None], steps[0], steps[1])
    step = np.where(np.isfinite(step), step, 0.0)
    ahead = xyz[before, a] + (after - before)[:, None] * step
    half = 0.5 * np.array(
        [_usual_distance(xyz[:, i], xyz[:, j]) for i, j in zip(a, b, strict=True)]
    )
    continues = np.linalg.norm(xyz[after, b] - ahead, axis=1) < half
    left = np.linalg.norm(xyz[after, a] - ahead, axis=1)
    gone = ~np.isfinite(left) | (left >= half)
    if fills is not None:
        gone |= fills[after, a]
    # Or, seen from both sides, a's path goes on through b's samples and not through a's
    # (gait9, BTS at 250 Hz: "r mall" leaps 28 then 66 mm a field while the foot moves 8,
    # and Mk23, 431 mm from it as a rule, takes up the path 5 mm from its extrapolation).
    rejoins = [_rejoins(xyz, *s) for s in zip(before, after, a, b, strict=True)]
    return int(np.sum(taken & ((gone & continues) | np.array(rejoins, dtype=bool))))


def _rejoins(xyz: np.ndarray, before: int, after: int, a: int, b: int, side: int = 3) -> bool:
    """Whether one cubic through channel ``a``'s last ``side`` samples up to ``before``
    and ``b``'s first from ``after`` fits them (RMS) under half as far as through ``a``'s
    own: a marker's path is smooth, so only a name that leaves it (the file's relabel)
    fits worse than another channel's samples do."""
    f = np.r_[before - side + 1 : before + 1, after : after + side]
    if f[0] < 0 or f[-1] >= len(xyz):
        return False
    t = np.vander(f - f.mean(), 4)
    rms = []
    for c in (a, b):
        p = np.r_[xyz[f[:side], a], xyz[f[side:], c]]
        if not np.isfinite(p).all():
            return False
        fit = t @ np.linalg.lstsq(t, p, rcond=None)[0]
        rms.append(np.sqrt(np.mean((p - fit) ** 2)))
    return bool(2.0 * rms[1] < rms[0])


def _usual_distance(p: np.ndarray, q: np.ndarray) -> float:
    """Median distance between two channels over the fields where both have a sample
    (infinite when they never do: then they cannot be told apart by it)."""
    both = np.isfinite(p[:, 0]) & np.isfinite(q[:, 0])
    return float(np.median(np.linalg.norm(p[both] - q[both], axis=1))) if both.any() else np.inf


def retrack(
    xyz: np.ndarray, rate_hz: float, seed: int = 0, params: TrackingParams | None = None
) -> Retrack:
    """Track a file's markers from shuffled anonymous points (default parameters unless
    ``params``); count identity switches (changes of true channel along each trajectory's
    measured samples) and coverage."""
    field, points, channel = shuffled(xyz, seed)
    params = reconstructed_points(params or TrackingParams())
    t0 = time.perf_counter()
    res = build_trajectories(field, points, params, rate_hz=rate_hz)
    dt = time.perf_counter() - t0
    tr = res.tracks
    ident = true_channel(tr, field, points, channel)
    switches = relabels = 0
    clean = distinct(xyz)
    fills = system_fills(clean)
    for t in range(tr.n_tracks):
        rows = np.flatnonzero((tr.track == t) & (tr.status == MEASURED))
        rows = rows[np.argsort(tr.field[rows])]
        ids, fields = ident[rows], tr.field[rows]
        at = np.flatnonzero(ids[1:] != ids[:-1])
        at = at[~shared_samples(xyz, clean, fields[at], fields[at + 1], ids[at], ids[at + 1])]
        switches += at.size
        relabels += file_relabels(clean, fields[at], fields[at + 1], ids[at], ids[at + 1], fills)
    held = len(np.unique(np.stack([tr.field, ident])[:, ident >= 0], axis=1).T)
    return Retrack(
        xyz.shape[1],
        xyz.shape[0],
        len(field),
        tr.n_tracks,
        switches,
        relabels,
        held / max(len(field), 1),
        dt,
    )


#: Plug-in Gait's arm markers: a full-body file without them is the partial-set case.
ARMS = tuple(f"{s}{m}" for s in "LR" for m in ("SHO", "UPA", "ELB", "FRM", "WRA", "WRB", "FIN"))


@dataclass(frozen=True)
class Labels:
    in_set: int
    right: int
    right_flagged: int
    named_wrong: int
    flagged_wrong: int
    extra_named: int
    seconds: float


def set_name(label: str, aliases: dict[str, str]) -> str:
    """A file's label as a marker set names it: without a subject prefix ("Derrick:"),
    through the set's aliases."""
    bare = label.rsplit(":", 1)[-1].strip().upper()
    return aliases.get(bare, bare)


def label_raw(
    c3d, set_name_: str, drop: tuple[str, ...] = (), turn: np.ndarray | None = None
) -> Labels:
    """Label a file's markers from a shipped set alone (labels dropped, every channel;
    the lab turned by the rotation ``turn`` when given: p -> turn @ p); count names
    right (and of them flagged), names on the wrong marker (silent or flagged) and names
    given to markers that are not in the set."""
    mset = marker_set(set_name_)
    names = [set_name(lab, mset.aliases) for lab in c3d.labels]
    keep = [i for i, n in enumerate(names) if n not in drop]
    xyz = distinct(c3d.xyz_mm[:, keep])
    if turn is not None:
        xyz = xyz @ turn.T
    names = [names[i] for i in keep]
    field, points, channel = shuffled(xyz)
    t0 = time.perf_counter()
    res = build_trajectories(
        field, points, reconstructed_points(TrackingParams()), marker_set=mset,
        rate_hz=c3d.rate_hz,
    )  # fmt: skip
    dt = time.perf_counter() - t0
    tr, lab = res.tracks, res.labelling
    ident = true_channel(tr, field, points, channel)
    unnamed = set(lab.unlabelled)
    got: dict[str, str] = {}
    wrong = flagged = extra = right_flagged = 0
    for t, label in enumerate(res.labels):
        ids = ident[(tr.track == t) & (ident >= 0)]
        if t in unnamed or label not in mset.names or not ids.size:
            continue  # unnamed (a labelling that gives up names every track M1, M2 ...)
        owner = names[int(np.bincount(ids).argmax())]
        if owner == label:
            got[owner] = label
            right_flagged += label in lab.flagged
        elif owner not in mset.names:
            extra += 1
        elif label in lab.flagged:
            flagged += 1
        else:
            wrong += 1
    in_set = len({n for n in names if n in mset.names})
    return Labels(in_set, len(got), right_flagged, wrong, flagged, extra, dt)


#: Files also labelled with the lab turned (the vertical found from the data): name,
#: variant, rotation (rows: the new axes in the file's; Z up becomes Y up, X down).
TURNED = (
    ("gait-pig-nz.c3d", "Y up", np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])),
    ("gait-pig-nz.c3d", "-X up", np.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]])),
    ("Vicon_analysis.c3d", "Y up", np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])),
)


def labels_report(cache: Path) -> list[str]:
    """One line per file (and variant: no arms, lab turned): names right, right but
    flagged, wrong and silent, wrong and flagged, names on markers outside the set."""
    lines = [
        f"{'file':34} {'set':18} {'in set':>6} {'right':>5} {'(flag)':>6} {'wrong':>5} "
        f"{'flagged':>7} {'extra':>5} {'s':>5}"
    ]
    for item in FILES + HELD_OUT:
        path = find(item.name, cache) if item.marker_set else None
        if path is None:
            continue
        c3d = read_c3d(path)
        variants = [(item.name, (), None)]
        if any(set_name(lab, {}) in ARMS for lab in c3d.labels):
            variants.append((f"{item.name} (no arms)", ARMS, None))
        variants += [(f"{n} ({v})", (), r) for n, v, r in TURNED if n == item.name]
        for name, drop, turn in variants:
            r = label_raw(c3d, item.marker_set, drop, turn)
            lines.append(
                f"{name:34} {item.marker_set:18} {r.in_set:6d} {r.right:5d} {r.right_flagged:6d} "
                f"{r.named_wrong:5d} {r.flagged_wrong:7d} {r.extra_named:5d} {r.seconds:5.1f}"
            )
    return lines


def report(cache: Path) -> list[str]:
    lines = [
        f"{'file':34} {'system':44} {'mk':>3} {'frames':>6} {'valid':>6} {'traj':>4} "
        f"{'switch':>6} {'relabel':>7} {'cover %':>7} {'s':>5}"
    ]
    for item in FILES + HELD_OUT:
        path = find(item.name, cache)
        if path is None:
            lines.append(f"{item.name:34} (not found)")
            continue
        try:
            c3d = read_c3d(path)
        except KisscalError as exc:
            lines.append(f"{item.name:34} {item.system:44} refused: {str(exc)[-70:]}")
            continue
        if not np.isfinite(c3d.xyz_mm).all(axis=2).any():
            lines.append(f"{item.name:34} {item.system:44} no valid sample in the file")
            continue
        r = retrack(c3d.xyz_mm, c3d.rate_hz)
        lines.append(
            f"{item.name:34} {item.system:44} {r.markers:3d} {r.frames:6d} {r.valid:6d} "
            f"{r.trajectories:4d} {r.switches:6d} {r.relabels:7d} {100 * r.coverage:7.2f} "
            f"{r.seconds:5.1f}"
        )
    return lines


if __name__ == "__main__":
    folder = cache_folder(sys.argv[1] if len(sys.argv) > 1 else None)
    print("\n".join(report(folder)))
    print()
    print("\n".join(labels_report(folder)))
