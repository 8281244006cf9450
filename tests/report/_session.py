"""A small processed session written straight to disk, with known truth.

Three cameras; a labelled gait-like trial (markers A, B, C on rigid segments, one gap, two
filled samples), a 502.5 mm stick, a thrown marker under known g, and a trial that
failed. Built in milliseconds so the report's tests need no pipeline run.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kisscal.io.files import write_table

RATE_HZ = 50.0
CAMERAS = ("cam1", "cam2", "cam3")
SEGMENT_AB_MM = 400.0
SEGMENT_BC_MM = 250.0
STICK_MM = 502.5
G_M_S2 = 9.81
NOISE_MM = 0.3
GAP_FIELDS = (40, 45)  # B missing in fields 40..44
FILLED_FIELDS = (70, 71)  # C filled there


@dataclass(frozen=True)
class Truth:
    root: Path
    n_fields: int


TOML = """
[session]
name = "report-test"
rate_hz = 50

[[cameras]]
id = "cam1"
size = [752, 291]

[[cameras]]
id = "cam2"
size = [752, 291]

[[cameras]]
id = "cam3"
size = [752, 291]

[markers]
names = ["A", "B", "C"]
segments = [["A", "B"], ["B", "C"]]

[report]
stick_length_mm = 502.5

[[trials]]
name = "walk"
centroids = "c/{camera}.csv"

[[trials]]
name = "stick"
centroids = "c/{camera}.csv"

[[trials]]
name = "throw"
centroids = "c/{camera}.csv"

[[trials]]
name = "broken"
centroids = "c/{camera}.csv"
"""


def _rows(tracks: list[tuple[str, np.ndarray, list[str]]]) -> dict[str, list]:
    cols: dict[str, list] = {k: [] for k in ("field", "track", "label", "x_mm", "y_mm", "z_mm")}
    cols["status"] = []
    for k, (label, xyz, status) in enumerate(tracks):
        for f, (p, s) in enumerate(zip(xyz, status, strict=True)):
            if s == "gap":
                continue
            cols["field"].append(f)
            cols["track"].append(k)
            cols["label"].append(label)
            cols["x_mm"].append(p[0])
            cols["y_mm"].append(p[1])
            cols["z_mm"].append(p[2])
            cols["status"].append(s)
    return cols


def _walk(rng: np.random.Generator, n: int) -> list[tuple[str, np.ndarray, list[str]]]:
    t = np.arange(n) / RATE_HZ
    a = np.column_stack([1000 * t, np.zeros(n), np.full(n, 900.0)])
    b = a - [0, 0, SEGMENT_AB_MM]
    c = b + [SEGMENT_BC_MM, 0, 0]
    status_b = ["gap" if GAP_FIELDS[0] <= f < GAP_FIELDS[1] else "measured" for f in range(n)]
    status_c = ["filled" if f in FILLED_FIELDS else "measured" for f in range(n)]
    noisy = [p + rng.normal(0, NOISE_MM, p.shape) for p in (a, b, c)]
    return [
        ("A", noisy[0], ["measured"] * n),
        ("B", noisy[1], status_b),
        ("C", noisy[2], status_c),
    ]


def _stick(rng: np.random.Generator, n: int) -> list[tuple[str, np.ndarray, list[str]]]:
    t = np.arange(n) / RATE_HZ
    centre = np.column_stack([500 * np.sin(t), 300 * np.cos(t), 1000 + 200 * np.sin(2 * t)])
    axis = np.column_stack([np.cos(t), np.sin(t), 0.3 * np.ones(n)])
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    ends = [centre + s * STICK_MM / 2 * axis for s in (-1, 1)]
    return [
        (f"M{k + 1}", p + rng.normal(0, NOISE_MM, p.shape), ["measured"] * n)
        for k, p in enumerate(ends)
    ]


def _throw(rng: np.random.Generator, n: int) -> list[tuple[str, np.ndarray, list[str]]]:
    t = np.arange(n) / RATE_HZ
    xyz = np.column_stack([-1000 + 2500 * t, 100 * t, 500 + 4000 * t - 0.5 * G_M_S2 * 1000 * t**2])
    return [("M1", xyz + rng.normal(0, NOISE_MM, xyz.shape), ["measured"] * n)]


def _summary(n: int) -> dict:
    cams = {
        c: {
            "grid": {"dots_used": 300, "rms_px_before": 1.7 + k, "rms_px": 0.0172 + k / 100},
            "dlt": {
                "method": "dlt",
                "rms_px": 0.0096 + k / 1000,
                "centre_mm": [-2528.3619711276333 + k, 4044.622259771918, 1671.8354937744284],
            },
        }
        for k, c in enumerate(CAMERAS)
    }
    trial = {
        "tracking": {"fits_marker_set": True, "missing": [], "trajectories": 3},
        "reconstruction": {
            "points": 3 * n,
            "rms_px_median": 0.0093,
            "points_by_n_cameras": [0, 0, 5, 7],
        },
    }
    loo = {
        "mean_mm": 0.3726,
        "max_mm": 0.471,
        "per_rod": {"R1": {"mean_mm": 0.31, "max_mm": 0.36, "n_markers": 6}},
    }
    return {
        "session": "report-test",
        "cameras": cams,
        "rods": {
            "rods_in_sample_mean_mm": 0.0324,
            "rods_in_sample_max_mm": 0.075,
            "leave_one_rod_out": loo,
        },
        "trials": {
            "walk": trial,
            "stick": {"tracking": {"fits_marker_set": False, "missing": ["A", "B", "C"]}},
            "throw": {"tracking": {"fits_marker_set": False, "missing": ["A", "B", "C"]}},
            "broken": {},
        },
        "timings": {"linearise_s": 1.2, "total_s": 9.9},
        "failed_trials": {"broken": "trial broken: c/cam2.csv: file not found"},
        "truth": {"walk": {"rmse_measured_mm": 0.3261235764486973, "matched": {"A": "A"}}},
    }  # fmt: skip


def _png() -> bytes:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(1, 1))
    FigureCanvasAgg(fig)
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=20)
    return buf.getvalue()


def write_session(root: Path, n_fields: int = 100, seed: int = 0) -> Truth:
    """Write the session to ``root``; return what it was built from."""
    rng = np.random.default_rng(seed)
    root.mkdir(parents=True, exist_ok=True)
    (root / "session.toml").write_text(TOML)
    out = root / "out"
    for name, tracks in (
        ("walk", _walk(rng, n_fields)),
        ("stick", _stick(rng, n_fields)),
        ("throw", _throw(rng, 45)),
    ):
        write_table(out / "trials" / name / "trajectories.csv", _rows(tracks))
    (out / "summary.json").write_text(json.dumps(_summary(n_fields)))
    figures = out / "figures"
    figures.mkdir(parents=True)
    for name in ("grid_cam1", "grid_gone", "trajectories_walk", "custom_extra"):
        (figures / f"{name}.png").write_bytes(_png())
    return Truth(root, n_fields)
