"""Where the shipped standing templates come from: anthropometric proportions -> marker mm.

The data files in ``kisscal/markersets/data`` are written by this module, a developer's
tool (``python -m tests.markersets.derive_markersets`` rewrites them; a test checks they
match), kept with the tests because the package never runs it: :mod:`kisscal.markersets`
only reads the files, and the KISS set is the synthetic walker's own geometry. The
geometry of every marker can be traced to a proportion of stature or to a published
landmark relation:

* Heights and lengths as fractions of stature ``H``: Winter 2009 (table after Drillis &
  Contini 1966): hip (greater trochanter) 0.530 H, knee 0.285 H, ankle 0.039 H, shoulder
  0.818 H, elbow 0.630 H, wrist 0.485 H, upper arm 0.186 H, forearm 0.146 H, hand
  0.108 H, foot length 0.152 H, head (chin to vertex) 0.130 H.
* Hip joint centre from the anterior iliac spines: Bell et al. 1990 (19 % of the inter-ASIS
  width posterior, 30 % distal, 36 % lateral of the ASIS midpoint); inter-ASIS width
  0.13 H and pelvis depth (ASIS to PSIS) 0.095 H, typical adult values (about 230 mm and
  165 mm at 1.75 m; Harrington et al. 2007 measured both on adults).
* Marker placement (which landmark each marker sits on): Davis et al. 1991 (the Helen
  Hayes / Plug-in Gait lower body) and the Vicon Plug-in Gait reference guide (head,
  trunk, arms); marker centres sit 7 mm (half a 14 mm marker) off the skin.
* Trunk landmark heights (C7 0.852 H, T10 0.720 H, jugular notch 0.812 H, xiphoid
  0.712 H): measured on the labelled Vicon trial shipped as ``kisscal/data/walking5.c3d``
  with its stature taken from its ASIS height (0.572 H, from the two rows above), and
  rounded; they agree with Dempster's trunk proportions within 0.01 H.

The SD given per marker combines where a marker is put (palpation and placement spread,
Della Croce et al. 1999 report 5-20 mm for pelvic and knee landmarks; wand markers on the
thigh, shank, upper arm and forearm are placed freely along the segment, 25-30 mm) with
the spread of body proportions once stature is known (3 % of the marker's distance from
the origin, the coefficient of variation of segment-to-stature ratios in adult
anthropometric surveys). The placement part is kept too (``placement_sd_mm``): a segment
length spreads by the two placements and 3 % of its length. Everything scales with
stature, as the template does (isometric scaling: ``xyz_mm * height_mm /
reference_height_mm``).

Frame of every template: X forward, Y left, Z up, millimetres; the floor is Z = 0 (feet
flat on it); the origin is on the floor below the midpoint of the hip joint centres.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kisscal.synth.motion import gait_marker_names, gait_segments, standing_template

#: Stature (mm) of the Plug-in Gait templates.
PIG_HEIGHT_MM = 1750.0
#: Stature (mm) of kisscal's synthetic walker: its hip height, 930 mm, is 0.530 H (Winter 2009).
KISS_HEIGHT_MM = 1755.0
#: Coefficient of variation of segment-to-stature ratios (see the module docstring).
PROPORTION_CV = 0.03
#: Inter-ASIS width and ASIS-to-PSIS depth as fractions of stature.
PELVIS_WIDTH, PELVIS_DEPTH = 0.13, 0.095
_MARKER_MM = 7.0

_DATA = Path(__file__).parents[2] / "kisscal" / "markersets" / "data"


def _left_leg(h: float) -> dict[str, tuple[np.ndarray, float, str]]:
    """Left-leg and pelvis markers: position (mm), placement SD (mm), landmark."""
    pw, depth = PELVIS_WIDTH * h, PELVIS_DEPTH * h
    hjc = np.array([0.0, 0.36 * pw, 0.530 * h])
    asis = np.array([0.19 * pw, 0.5 * pw, hjc[2] + 0.30 * pw])  # Bell et al. 1990
    psis = np.array([asis[0] - depth, 50.0, asis[2] + 25.0])  # anterior pelvic tilt ~9 deg
    kjc = np.array([0.0, 0.95 * hjc[1], 0.285 * h])
    ajc = np.array([0.0, 0.90 * hjc[1], 0.039 * h])
    foot = 0.152 * h
    heel_x = -0.30 * foot  # ankle joint above the back third of the foot
    thigh_c = kjc + (hjc - kjc) / 3.0  # lower third of the thigh
    shank_c = ajc + (kjc - ajc) / 3.0  # lower third of the shank
    return {
        "LASI": (asis, 10.0, "left anterior superior iliac spine"),
        "LPSI": (psis, 10.0, "left posterior superior iliac spine"),
        "LTHI": (thigh_c + [0, 0.046 * h, 0], 25.0, "left thigh wand, lower lateral third"),
        "LKNE": (kjc + [0, 0.030 * h + _MARKER_MM, 0], 12.0, "left lateral femoral epicondyle"),
        "LTIB": (shank_c + [0, 0.024 * h + _MARKER_MM, 0], 25.0, "left shank wand, lower third"),
        "LANK": (ajc + [0, 0.020 * h + _MARKER_MM, 0], 8.0, "left lateral malleolus"),
        "LHEE": (
            np.array([heel_x - _MARKER_MM, ajc[1], 40.0]),
            10.0,
            "left calcaneus, same height above the sole as LTOE",
        ),
        "LTOE": (
            np.array([heel_x + 0.80 * foot, ajc[1], 40.0]),
            10.0,
            "left second metatarsal head, dorsum",
        ),
    }


def _left_upper(h: float) -> dict[str, tuple[np.ndarray, float, str]]:
    """Left head and arm markers: arms hanging 10 degrees abducted, palms to the thighs."""
    down = np.array([0.0, np.sin(np.radians(10.0)), -np.cos(np.radians(10.0))])
    out = np.array([0.0, np.cos(np.radians(10.0)), np.sin(np.radians(10.0))])
    sjc = np.array([-20.0, 0.100 * h, 0.818 * h])
    elbow = sjc + 0.186 * h * down
    wrist = elbow + 0.146 * h * down
    head_x, head_z = -20.0, 0.935 * h
    return {
        "LFHD": (np.array([head_x + 90.0, 55.0, head_z + 10.0]), 20.0, "left temple"),
        "LBHD": (np.array([head_x - 95.0, 50.0, head_z]), 20.0, "left back of the head"),
        "LSHO": (sjc + [0.0, 15.0, 40.0], 12.0, "left acromio-clavicular joint"),
        "LUPA": (sjc + 0.5 * 0.186 * h * down + 55.0 * out, 30.0, "left upper arm wand"),
        "LELB": (elbow + 40.0 * out, 12.0, "left lateral humeral epicondyle"),
        "LFRM": (elbow + 0.5 * 0.146 * h * down + 50.0 * out, 30.0, "left forearm wand"),
        "LWRA": (wrist + [28.0, 0.0, 0.0], 8.0, "left radial styloid (thumb side)"),
        "LWRB": (wrist + [-28.0, 0.0, 0.0], 8.0, "left ulnar styloid (little-finger side)"),
        "LFIN": (
            wrist + 0.065 * h * down + 20.0 * out + [20.0, 0.0, 0.0],
            15.0,
            "left hand, dorsum just proximal to the second metacarpal head",
        ),
    }


def _midline(h: float) -> dict[str, tuple[np.ndarray, float, str]]:
    pw, depth = PELVIS_WIDTH * h, PELVIS_DEPTH * h
    asis_z = 0.530 * h + 0.30 * pw
    return {
        "SACR": (np.array([0.19 * pw - depth, 0.0, asis_z + 25.0]), 10.0, "midpoint of the PSIS"),
        "C7": (np.array([-80.0, 0.0, 0.852 * h]), 10.0, "spinous process of C7"),
        "T10": (np.array([-125.0, 0.0, 0.720 * h]), 15.0, "spinous process of T10"),
        "CLAV": (np.array([60.0, 0.0, 0.812 * h]), 10.0, "jugular notch"),
        "STRN": (np.array([105.0, 0.0, 0.712 * h]), 15.0, "xiphoid process"),
    }


def _mirror(left: dict[str, tuple[np.ndarray, float, str]]) -> dict[str, tuple]:
    flip = np.array([1.0, -1.0, 1.0])
    return {
        "R" + k[1:]: (v * flip, sd, text.replace("left", "right", 1))
        for k, (v, sd, text) in left.items()
    }


def _markers_table(markers: dict[str, tuple], names: list[str]) -> dict[str, dict]:
    table = {}
    for name in names:
        xyz, place_sd, text = markers[name]
        sd = float(np.hypot(place_sd, PROPORTION_CV * np.linalg.norm(xyz)))
        table[name] = {
            "xyz_mm": [round(float(c), 2) for c in xyz],
            "sd_mm": round(sd, 1),
            "placement_sd_mm": float(place_sd),
            "landmark": text,
        }
    return table


_PELVIS = ["LASI", "RASI", "LPSI", "RPSI"]
_LEG = ["THI", "KNE", "TIB", "ANK", "HEE", "TOE"]
_LOWER = _PELVIS + [s + m for s in "LR" for m in _LEG]
_ARM = ["SHO", "UPA", "ELB", "FRM", "WRA", "WRB", "FIN"]
_FULL = (
    ["LFHD", "RFHD", "LBHD", "RBHD", "C7", "T10", "CLAV", "STRN", "RBAK"]
    + [s + m for s in "LR" for m in _ARM]
    + _LOWER
)


def _pairs_all(names: list[str]) -> list[list[str]]:
    return [[a, b] for i, a in enumerate(names) for b in names[i + 1 :]]


def _lower_segments(sides: str = "LR") -> tuple[list[list[str]], list[list[str]]]:
    rigid = _pairs_all(["LASI", "RASI", "LPSI", "RPSI", "SACR"])
    hinge = []
    for s in sides:
        rigid += [[f"{s}THI", f"{s}KNE"], [f"{s}TIB", f"{s}ANK"], [f"{s}HEE", f"{s}TOE"]]
        hinge += [
            [f"{s}KNE", f"{s}TIB"],
            [f"{s}KNE", f"{s}ANK"],
            [f"{s}ANK", f"{s}HEE"],
            [f"{s}ANK", f"{s}TOE"],
        ]
    return rigid, hinge


def _roles(heel: str = "HEE", toe: str = "TOE", ankle: str = "ANK") -> dict:
    return {
        "pelvis": ["LASI", "RASI", "LPSI", "RPSI", "SACR"],
        "left": {"heel": "L" + heel, "toe": "L" + toe, "ankle": "L" + ankle},
        "right": {"heel": "R" + heel, "toe": "R" + toe, "ankle": "R" + ankle},
    }


_FRAME = (
    "X forward, Y left, Z up, mm; floor at Z = 0 with the feet flat on it; origin on the "
    "floor below the midpoint of the hip joint centres"
)
_PIG_SOURCE = (
    "Proportions of stature: Winter 2009 (after Drillis & Contini 1966); hip joint centre: "
    "Bell et al. 1990; placement: Davis et al. 1991 and the Vicon Plug-in Gait reference "
    "guide; SD: Della Croce et al. 1999 plus 3 % proportion spread. Derivation: "
    "tests/markersets/derive_markersets.py"
)
#: Names the OpenSim / Vicon FULLBODY_2009 set (walking5.c3d) gives the same landmarks.
WALKING5_ALIASES = {
    "LCAL": "LHEE",
    "RCAL": "RHEE",
    "LMT2": "LTOE",
    "RMT2": "RTOE",
    "LLMAL": "LANK",
    "RLMAL": "RANK",
    "LLFC": "LKNE",
    "RLFC": "RKNE",
}


def plug_in_gait(full: bool) -> dict:
    """The Plug-in Gait lower-body (16 + SACR) or full-body (39 + SACR) set as a data table."""
    h = PIG_HEIGHT_MM
    markers = {**_left_leg(h), **_mirror(_left_leg(h)), **_midline(h)}
    if full:
        markers |= _left_upper(h) | _mirror(_left_upper(h))
        markers["RBAK"] = (np.array([-120.0, -85.0, 0.78 * h]), 30.0, "right scapula (asymmetric)")
    names = _FULL if full else _LOWER
    rigid, hinge = _lower_segments()
    mirror = [[f"L{m}", f"R{m}"] for m in ("ASI", "PSI", *_LEG)]
    midline = ["SACR"]
    if full:
        rigid += _pairs_all(["LFHD", "RFHD", "LBHD", "RBHD"]) + _pairs_all(
            ["C7", "T10", "CLAV", "STRN"]
        )
        for s in "LR":
            rigid += [[f"{s}UPA", f"{s}ELB"]] + _pairs_all([f"{s}FRM", f"{s}WRA", f"{s}WRB"])
            hinge += [[f"{s}ELB", f"{s}FRM"], [f"{s}ELB", f"{s}WRA"], [f"{s}ELB", f"{s}WRB"]]
        mirror += [[f"L{m}", f"R{m}"] for m in ("FHD", "BHD", *_ARM)]
        midline += ["C7", "T10", "CLAV", "STRN"]
    return {
        "name": "plug-in-gait-full" if full else "plug-in-gait-lower",
        "description": (
            "Vicon Plug-in Gait full body (39 markers)"
            if full
            else "Vicon Plug-in Gait lower body (16 markers; SACR may replace LPSI and RPSI)"
        ),
        "reference_height_mm": h,
        "proportion_cv": PROPORTION_CV,
        "frame": _FRAME,
        "source": _PIG_SOURCE,
        "names": names,
        "alternatives": {"SACR": ["LPSI", "RPSI"]},
        "segments": rigid,
        "hinge_segments": hinge,
        "mirror": mirror,
        "midline": midline,
        "roles": _roles(),
        "aliases": dict(WALKING5_ALIASES),
        "markers": _markers_table(markers, [*names, "SACR"]),
    }


def kiss() -> dict:
    """The KISS set of kisscal's synthetic walker (Küçük 2005): 15 markers, or 13 without ASIS."""
    names = list(gait_marker_names(15))
    xyz = standing_template(tuple(names))
    place = {"SACR": 10, "ASI": 10, "THI": 25, "KNE": 12, "TIB": 25, "ANK": 8, "HEE": 10, "TOE": 10}
    markers = {}
    for name, p in zip(names, xyz, strict=True):
        key = name if name == "SACR" else name[1:]
        side = {"L": "left", "R": "right"}.get(name[0], "")
        markers[name] = (p, float(place[key]), f"{side} {key} marker of the KISS walker".strip())
    rigid = [list(p) for p in gait_segments(tuple(names))]
    return {
        "name": "kiss",
        "description": (
            "The KISS gait lab set (Küçük 2005) as kisscal's synthetic walker carries it: "
            "sacrum, both ASIS, thigh, knee, shank, ankle, heel and toe per leg; "
            "names = the 13 without RASI and LASI for the thesis' 13-marker set"
        ),
        "reference_height_mm": KISS_HEIGHT_MM,
        "proportion_cv": PROPORTION_CV,
        "frame": _FRAME,
        "source": (
            "kisscal.synth.motion.standing_template (the walker's geometry: thigh 430 mm, "
            "shank 420 mm, hip half-width 85 mm); stature from its hip height, 0.530 H "
            "(Winter 2009); SD as for Plug-in Gait (tests/markersets/derive_markersets.py)"
        ),
        "names": names,
        "alternatives": {},
        "segments": rigid,
        "hinge_segments": [],
        "mirror": [["LASI", "RASI"]] + [[f"L{m}", f"R{m}"] for m in _LEG],
        "midline": ["SACR"],
        "roles": _roles(),
        "aliases": {},
        "markers": _markers_table(markers, names),
    }


def tables() -> dict[str, dict]:
    """Every shipped set as the table its data file holds, by file stem."""
    return {
        "plug-in-gait-lower": plug_in_gait(full=False),
        "plug-in-gait-full": plug_in_gait(full=True),
        "kiss": kiss(),
    }


def _toml_value(value: object) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, float | int):
        return repr(float(value)) if isinstance(value, float) else str(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(type(value))


def _toml_list(key: str, values: list) -> str:
    """A long list, a few items a line."""
    items = [_toml_value(v) for v in values]
    per_line = 6 if values and isinstance(values[0], list) else 10
    lines = [", ".join(items[i : i + per_line]) for i in range(0, len(items), per_line)]
    return f"{key} = [\n    " + ",\n    ".join(lines) + ",\n]\n"


def to_toml(table: dict) -> str:
    """The data-file text of one set (a compact TOML layout, read back by ``tomllib``)."""
    out = [
        "# Written by tests/markersets/derive_markersets.py; see its docstring for the sources.\n"
    ]
    for key, value in table.items():
        if isinstance(value, list) and len(value) > 4:
            out.append(_toml_list(key, value))
        elif not isinstance(value, dict):
            out.append(f"{key} = {_toml_value(value)}\n")
    for key in ("alternatives", "aliases"):
        out.append(f"\n[{key}]\n")
        out += [f"{k} = {_toml_value(v)}\n" for k, v in table[key].items()]
    roles = table["roles"]
    out.append(f"\n[roles]\npelvis = {_toml_value(roles['pelvis'])}\n")
    for side in ("left", "right"):
        inner = ", ".join(f"{k} = {_toml_value(v)}" for k, v in roles[side].items())
        out.append(f"{side} = {{ {inner} }}\n")
    for name, m in table["markers"].items():
        out.append(f"\n[markers.{name}]\n")
        out += [f"{k} = {_toml_value(v)}\n" for k, v in m.items()]
    return "".join(out)


def main() -> None:
    """Rewrite the data files from the derivation above."""
    for stem, table in tables().items():
        (_DATA / f"{stem}.toml").write_text(to_toml(table), encoding="utf-8")


if __name__ == "__main__":
    main()
