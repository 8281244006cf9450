"""Real gait trials with marked events: the regression set in fixtures/real/gait/.

Each fixture is a C3D file trimmed to the markers gait events need (pelvis, heel, toe;
the ankle where a trial has no heel marker), with the source's frame numbering and its
EVENT group (``Foot Strike`` / ``Foot Off`` per context) kept. ``TRIALS`` says where each
came from, which system wrote it and which marker plays which role; the README beside
the files gives the licences.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kisscal.gait import GaitMarkers, heel_from_ankle

#: The group holding the force plates' contacts (20 N) in each fixture.
PLATE_GROUP = "PLATE_EVENT"
FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "real" / "gait"
_C3DORG = "biomechanics-foundation/c3dio:tests/c3d_org_samples/"


@dataclass(frozen=True)
class RealTrial:
    """One trial: fixture name, source, system, the marker of each role, and notes."""

    name: str
    source: str
    system: str
    pelvis: tuple[str, ...]
    heel: tuple[str, str]  # left, right
    toe: tuple[str, str]
    events_from: str = "EVENT group as the lab saved it"
    note: str = ""
    #: The lab's vertical axis ("z", or "y" for a Y-up lab: turned to z up on loading).
    up: str = "z"
    #: Score against the plates' contacts too (not on a treadmill: a foot crossing onto
    #: the other belt loads it, so a belt's contacts are not one foot's stance).
    plates: bool = True
    #: A held-out trial: the source file's name in the C3D cache (``cache_folder``), read
    #: whole unless a trimmed fixture of its name is committed; its plates' contacts are
    #: found on loading.
    file: str = ""

    @property
    def path(self) -> Path:
        trimmed = FIXTURES / f"{self.name}.c3d"
        if not self.file or trimmed.is_file():
            return trimmed
        return self.source_file

    @property
    def source_file(self) -> Path:
        """A held-out trial's whole source file in the C3D cache (its force plates: a
        trimmed fixture keeps none)."""
        hits = sorted(cache_folder().rglob(self.file)) if cache_folder().is_dir() else []
        return hits[0] if hits else cache_folder() / "c3dio" / self.file

    @property
    def markers(self) -> tuple[str, ...]:
        return (*self.pelvis, *self.heel, *self.toe)

    @property
    def ankle(self) -> bool:
        """Whether the 'heel' markers are ankle markers (the feet carry no heel one)."""
        return "ankle" in self.note.lower() or all("ANK" in n.upper() for n in self.heel)


_PIG = ("LASI", "RASI", "LPSI", "RPSI")
_PLATES = "force plates (20 N), the foot over the plate"
_ANKLE = "the ankle (ANK) stands in for the heel"
TRIALS = (
    RealTrial(
        "gaitalytics_treadmill",
        "DART-Lab-LLUI/python-gaitalytics:tests/treadmill_events.c3d",
        "Vicon Nexus, instrumented treadmill",
        ("LASIS", "RASIS", "LPSIS", "RPSIS"),
        ("LHEE", "RHEE"),
        ("LMT2", "RMT2"),
        note="treadmill: the pelvis hardly moves in the lab",
        plates=False,
    ),
    RealTrial(
        "gaitalytics_overground",
        "DART-Lab-LLUI/python-gaitalytics:tests/full/data/test_small.c3d",
        "Vicon Nexus",
        ("LASI", "RASI", "SACR"),
        ("LHEE", "RHEE"),
        ("LTOE", "RTOE"),
    ),
    RealTrial(
        "pycgm2_walking01",
        _C3DORG + "sample_00/Vicon Motion Systems/pyCGM2 lower limb CGM24 Walking01.c3d",
        "Vicon Nexus (pyCGM2 CGM2.4)",
        _PIG,
        ("LHEE", "RHEE"),
        ("LTOE", "RTOE"),
    ),
    RealTrial(
        "vicon_zerowire",
        _C3DORG + "sample_32/vicon_zerowire.c3d",
        "Vicon Nexus",
        _PIG,
        ("LHEE", "RHEE"),
        ("LTOE", "RTOE"),
    ),
    RealTrial(
        "vicon_ws44_plugingait",
        _C3DORG + "sample_09/PlugInC3D.c3d",
        "Vicon Workstation 4.4 (Plug-in Gait)",
        ("LASI", "RASI", "SACR"),
        ("LHEE", "RHEE"),
        ("LTOE", "RTOE"),
    ),
    RealTrial(
        "vicon_sub_labels",
        _C3DORG + "sample_04/sub_labels.c3d",
        "Vicon 370 / Workstation",
        ("Matt:LASI", "Matt:RASI", "Matt:SACR"),
        ("Matt:LANK", "Matt:RANK"),
        ("Matt:LTOE", "Matt:RTOE"),
        note="its heel markers hold no data: " + _ANKLE,
    ),
    RealTrial(
        "motion_analysis_walk1",
        _C3DORG + "sample_00/Motion Analysis Corporation/Walk1.c3d",
        "Motion Analysis Corporation (Cortex)",
        ("LASI", "RASI", "VSAC"),
        ("LHEE", "RHEE"),
        ("L.TO", "R.TO"),
        events_from="EVENT group (LHS/RHS/LTO/RTO labels)",
    ),
    RealTrial(
        "vicon_analysis",
        _C3DORG + "sample_23/Vicon_analysis.c3d",
        "Vicon (processed by Motion Lab Systems software)",
        ("LASI", "RASI", "SACR"),
        ("LANK", "RANK"),
        ("LTOE", "RTOE"),
        note="no heel marker: " + _ANKLE,
    ),
    RealTrial(
        "vicon_2198928",
        _C3DORG + "sample_11/2198928.c3d",
        "Vicon (a Vicon user's lab)",
        ("LASI", "RASI", "SACR"),
        ("LANK", "RANK"),
        ("LTOE", "RTOE"),
        note="no heel marker: " + _ANKLE,
    ),
    RealTrial(
        "vicon370_gait_pig_nz",
        _C3DORG + "sample_03/gait-pig-nz.c3d",
        "Vicon 370 (Plug-in Gait)",
        ("LASI", "RASI", "SACR"),
        ("LANK", "RANK"),
        ("LTOE", "RTOE"),
        note="no heel marker: " + _ANKLE,
    ),
    RealTrial(
        "qualisys_walking_1_3",
        _C3DORG + "sample_26/Walking_Hybrid_1_3.c3d",
        "Qualisys",
        ("L_ASIS", "R_ASIS", "SACRUM"),
        ("L_HEEL", "R_HEEL"),
        ("L_MT_1", "R_MT_1"),
        events_from=_PLATES,
    ),
    RealTrial(
        "qualisys_walking_1_4",
        _C3DORG + "sample_26/Walking_Hybrid_1_4.c3d",
        "Qualisys",
        ("L_ASIS", "R_ASIS", "SACRUM"),
        ("L_HEEL", "R_HEEL"),
        ("L_MT_1", "R_MT_1"),
        events_from=_PLATES,
    ),
    RealTrial(
        "qualisys_walking_1_5",
        _C3DORG + "sample_26/Walking_Hybrid_1_5.c3d",
        "Qualisys",
        ("L_ASIS", "R_ASIS", "SACRUM"),
        ("L_HEEL", "R_HEEL"),
        ("L_MT_1", "R_MT_1"),
        events_from=_PLATES,
    ),
    RealTrial(
        "qualisys_ezc3d",
        "kineticstoolkit/kineticstoolkit:data/c3d_test_suite/ezc3d/Qualisys.c3d",
        "Qualisys (QTM)",
        ("L_IAS", "R_IAS", "L_IPS", "R_IPS"),
        ("L_FCC", "R_FCC"),
        ("L_FM1", "R_FM1"),
        events_from=_PLATES,
    ),
    RealTrial(
        "codamotion_gaitwands",
        _C3DORG + "sample_00/Codamotion/codamotion_gaitwands_20150204.c3d",
        "Codamotion (Charnwood Dynamics)",
        ("L.ASIS", "R.ASIS", "L.PSIS", "R.PSIS"),
        ("L.Heel", "R.Heel"),
        ("L.Toe", "R.Toe"),
        events_from=_PLATES,
    ),
    RealTrial(
        "bts_gait",
        "kineticstoolkit/kineticstoolkit:data/c3d_test_suite/ezc3d/BTS.c3d",
        "BTS Bioengineering (Y up)",
        ("l asis", "r asis", "sacrum"),
        ("l heel", "r heel"),
        ("l met", "r met"),
        events_from=_PLATES,
        up="y",
    ),
    RealTrial(
        "opensim_walking2",
        "opensim-org/opensim-core:OpenSim/Tests/shared/walking2.c3d",
        "Vicon",
        ("LASI", "RASI", "LPSI", "RPSI"),
        ("LCAL", "RCAL"),
        ("LMT2", "RMT2"),
        events_from=_PLATES,
    ),
    RealTrial(
        "opensim_walking5",
        "opensim-org/opensim-core:OpenSim/Tests/shared/walking5.c3d",
        "Vicon",
        ("LASI", "RASI", "LPSI", "RPSI"),
        ("LCAL", "RCAL"),
        ("LMT2", "RMT2"),
        events_from=_PLATES,
    ),
)

_A22 = tuple(f"A22:{n}" for n in ("LASI", "RASI", "SACR"))
#: Held out: every C3D.org sample file of ``tests.io.c3d_acceptance.HELD_OUT`` (the
#: cache's ``c3dio/``) not in ``TRIALS`` above whose lab marked its foot strikes and foot
#: offs (EVENT group) or whose force plates see a foot's contact, with the markers the
#: events need; first scored blind (issue 26), not kept in the fixtures. Left out:
#: evart.c3d (DEC, 17 analog samples a frame by its header, 16.67 by its rates): ezc3d,
#: which reads the plates here, lays its frames out wrong (kisscal's reader reads its
#: markers right, but no analog channels), so its plates' contacts are not known.
HELD_OUT = (
    RealTrial(
        "heldout_gait_pig",
        _C3DORG + "gait-pig.c3d",
        "Vicon 370 (Plug-in Gait)",
        _A22,
        ("A22:LANK", "A22:RANK"),
        ("A22:LTOE", "A22:RTOE"),
        note="no heel marker: " + _ANKLE,
        file="gait-pig.c3d",
    ),
    RealTrial(
        "heldout_newwalk",
        _C3DORG + "newwalk.c3d",
        "Motion Analysis (EVaRT)",
        ("LASI", "RASI"),
        ("LHEE", "RHEE"),
        ("LTOE", "RTOE"),
        events_from=_PLATES,
        file="newwalk.c3d",
    ),
    RealTrial(
        "heldout_type3",
        _C3DORG + "TYPE-3.c3d",
        "AMTI type-3 plates sample (Vicon markers)",
        ("LASI", "RASI", "SACR"),
        ("LHEE", "RHEE"),
        ("LTOE", "RTOE"),
        events_from=_PLATES,
        file="TYPE-3.c3d",
    ),
    RealTrial(
        "heldout_sample14",
        _C3DORG + "sample14.c3d",
        "Vicon",
        ("LASI", "RASI", "SACR"),
        ("LANK", "RANK"),
        ("LTOE", "RTOE"),
        events_from=_PLATES,
        note="its heel marker holds no data: " + _ANKLE,
        file="sample14.c3d",
    ),
    RealTrial(
        "heldout_codamotion_1997",
        _C3DORG + "codamotion_gaitwands_19970212.c3d",
        "Codamotion (Charnwood Dynamics)",
        ("L.ASIS", "R.ASIS", "L.PSIS", "R.PSIS"),
        ("L.Heel", "R.Heel"),
        ("L.Toe", "R.Toe"),
        events_from=_PLATES,
        file="codamotion_gaitwands_19970212.c3d",
    ),
    RealTrial(
        "heldout_analogfpscale03",
        _C3DORG + "analogfpscale03.c3d",
        "Vicon",
        tuple(f"IS070607:{n}" for n in _PIG),
        ("IS070607:LHEE", "IS070607:RHEE"),
        ("IS070607:LTOE", "IS070607:RTOE"),
        events_from=_PLATES,
        file="analogfpscale03.c3d",
    ),
    RealTrial(
        "heldout_capture0002",
        _C3DORG + "Capture0002.c3d",
        "Qualisys",
        ("l_asis", "r_asis", "sacrum"),
        ("l_heel", "r_heel"),
        ("l_toe", "r_toe"),
        events_from=_PLATES,
        file="Capture0002.c3d",
    ),
    RealTrial(
        "heldout_walking_1_1",
        _C3DORG + "Walking_Hybrid_1_1.c3d",
        "Qualisys",
        ("L_ASIS", "R_ASIS", "SACRUM"),
        ("L_HEEL", "R_HEEL"),
        ("L_MT_1", "R_MT_1"),
        events_from=_PLATES,
        file="Walking_Hybrid_1_1.c3d",
    ),
    RealTrial(
        "heldout_walking_2",
        _C3DORG + "Walking_Hybrid_2.c3d",
        "Qualisys",
        ("L_ASIS", "R_ASIS", "SACRUM"),
        ("L_HEEL", "R_HEEL"),
        ("L_MT_1", "R_MT_1"),
        events_from=_PLATES,
        file="Walking_Hybrid_2.c3d",
    ),
)


_ZOO = "PhilD001/biomechZoo:sample-study/Data/raw c3d files/"
#: Vicon Nexus walking trials of biomechZoo's sample study (commit 38e00d95; straight and
#: turning walks, two force plates, trajectories filtered before saving): the six
#: subjects foot off was tuned on (issue 26); the study's six others are held out and
#: not kept here (``python -m tests.gait.folder_events FOLDER`` scores them).
ZOO = tuple(
    RealTrial(
        f"zoo_{n}",
        f"{_ZOO}{n[:6]}/{walk}/{n}.c3d",
        "Vicon Nexus (biomechZoo sample study)",
        ("LASI", "RASI", "SACR"),
        ("LHEE", "RHEE"),
        ("LTOE", "RTOE"),
        note=f"{walk.lower()} walk",
    )
    for n, walk in (
        ("HC002D06", "Straight"),
        ("HC002D25", "Turn"),
        ("HC031A23", "Turn"),
        ("HC033A10", "Straight"),
        ("HC033A22", "Turn"),
        ("HC038A11", "Straight"),
        ("HC038A27", "Turn"),
        ("HC040A14", "Straight"),
        ("HC050A11", "Straight"),
        ("HC050A33", "Turn"),
    )
)


def cache_folder() -> Path:
    """Where the held-out files are: ``$KISSCAL_C3D_CACHE`` or ``../shared/data/real/c3d``
    (as ``tests.io.c3d_acceptance``)."""
    import os

    default = Path(__file__).resolve().parents[3] / "shared" / "data" / "real" / "c3d"
    return Path(os.environ.get("KISSCAL_C3D_CACHE") or default)


_SIDE = {"left": "left", "right": "right"}
_MM = {"mm": 1.0, "cm": 10.0, "m": 1000.0}


def z_up(xyz: np.ndarray, up: str) -> np.ndarray:
    """Points (..., 3) of a lab whose vertical is ``up`` turned so that z is up (a
    proper rotation about x for a Y-up lab)."""
    if up == "z":
        return xyz
    if up == "y":
        return np.stack([xyz[..., 0], -xyz[..., 2], xyz[..., 1]], axis=-1)
    raise ValueError(f"unknown vertical axis {up!r}")


_LABEL = {"foot strike": "foot_strike", "foot off": "foot_off"}
_SHORT = {"LHS": ("left", "foot_strike"), "RHS": ("right", "foot_strike")}
_SHORT |= {"LTO": ("left", "foot_off"), "RTO": ("right", "foot_off")}


def read(path: Path | str, group: str = "EVENT") -> tuple[dict[str, np.ndarray], float, int, dict]:
    """Markers (name -> (n, 3) mm, NaN where invalid), rate, first frame (0-based) and
    the events of ``group`` as ``(side, event) -> times (s, 0 at the first frame
    stored)``."""
    import ezc3d

    c3d = ezc3d.c3d(str(path))
    params = c3d["parameters"]
    rate = float(params["POINT"]["RATE"]["value"][0])
    first = int(c3d["header"]["points"]["first_frame"])
    xyz = c3d["data"]["points"][:3].transpose(2, 1, 0).copy()
    xyz[np.all(xyz == 0.0, axis=2)] = np.nan  # older writers store a missing sample as 0 0 0
    xyz *= mm_per_unit(params)
    markers = dict(zip(point_labels(params), xyz.transpose(1, 0, 2), strict=True))
    return markers, rate, first, _events(params.get(group, {}), first / rate)


def mm_per_unit(params: dict) -> float:
    """Millimetres per POINT:UNITS (1 when the file gives none: a file without points)."""
    units = params["POINT"].get("UNITS", {}).get("value", []) or [""]
    return _MM.get(units[0].strip().lower(), 1.0)


def point_labels(params: dict) -> list[str]:
    """POINT:LABELS, then LABELS2, LABELS3 (a file of more than 255 points)."""
    point = params["POINT"]
    return [n for g in ("", "2", "3") for n in point.get(f"LABELS{g}", {}).get("value", [])]


def _events(group: dict, start_s: float) -> dict[tuple[str, str], np.ndarray]:
    """The EVENT group's foot strikes and foot offs; Vicon's time is frame (1-based) - 1
    over the rate, so the first stored frame is at ``start_s``."""
    labels = group.get("LABELS", {}).get("value", [])
    contexts = group.get("CONTEXTS", {}).get("value", [""] * len(labels))
    times = np.asarray(group.get("TIMES", {}).get("value", np.zeros((2, 0))), dtype=float)
    if times.ndim == 1:  # BTK writes TIMES flat: minutes, seconds, minutes, ...
        times = times.reshape(-1, 2).T
    out: dict[tuple[str, str], list[float]] = {}
    if not labels:  # ezc3d reads a blank event list back as no labels
        return {}
    for label, context, (minutes, seconds) in zip(labels, contexts, times.T, strict=True):
        key = _SHORT.get(context.strip()) or _SHORT.get(label.strip())
        side, event = context.strip().lower(), _LABEL.get(label.strip().lower())
        if key is None and side in _SIDE and event:
            key = (side, event)
        if key:
            out.setdefault(key, []).append(60.0 * minutes + seconds - start_s)
    return {k: np.sort(v) for k, v in out.items()}


def load(
    trial: RealTrial, group: str = "EVENT", stand_in: bool = True
) -> tuple[GaitMarkers, dict[tuple[str, str], np.ndarray]]:
    """The trial's gait markers and marked events (s from its first stored frame);
    ``group=PLATE_GROUP``: the force plates' contacts instead. A foot without a heel
    marker gets kisscal's heel stand-in behind its ankle marker (``stand_in=False``: the
    ankle marker itself)."""
    markers, rate, _, events = read(trial.path, group)
    if trial.file and group == PLATE_GROUP:  # a source file: its plates' contacts
        events = _plates(trial, markers, rate)
    markers = {k: z_up(v, trial.up) for k, v in markers.items()}
    heel = dict(zip(("left", "right"), (markers[n] for n in trial.heel), strict=True))
    toe = dict(zip(("left", "right"), (markers[n] for n in trial.toe), strict=True))
    pelvis = tuple(markers[n] for n in trial.pelvis if n in markers)
    names = {"pelvis": ",".join(trial.pelvis)}
    names |= {f"{s}_heel": n for s, n in zip(("left", "right"), trial.heel, strict=True)}
    if not (trial.ankle and stand_in):
        return GaitMarkers(pelvis, heel, toe, rate, names), events
    heel = {side: heel_from_ankle(heel[side], toe[side]) for side in heel}
    return GaitMarkers(pelvis, heel, toe, rate, names, ("left", "right")), events


def _plates(trial: RealTrial, markers: dict, rate: float) -> dict[tuple[str, str], np.ndarray]:
    """The plates' contacts of a held-out source file, as the fixtures' PLATE_EVENT."""
    import ezc3d

    from tests.gait.make_real_fixtures import plate_events

    if not trial.source_file.is_file():
        return {}
    c3d = ezc3d.c3d(str(trial.source_file))
    params = c3d["parameters"]
    if "FORCE_PLATFORM" not in params:
        return {}
    mm = mm_per_unit(params)
    mk = {k: z_up(v, trial.up) for k, v in markers.items()}
    roles = [
        {s: mk[n] for s, n in zip(("left", "right"), r, strict=True)}
        for r in (trial.heel, trial.toe)
    ]
    out: dict[tuple[str, str], list[float]] = {}
    for side, label, t in plate_events(c3d, *roles, rate, trial.up, mm):
        out.setdefault((side.lower(), _LABEL[label.lower()]), []).append(t)
    return {k: np.sort(v) for k, v in out.items()}
