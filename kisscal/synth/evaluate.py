"""Scoring a processed synthetic session against its ground truth.

Pure functions on arrays: the demo, the end-to-end tests and the benchmarks read the
trajectories and the truth tables (``kisscal.io``) and pass them here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from kisscal.synth.motion import STICK_LENGTH_MM


@dataclass(frozen=True)
class TrajectoryScore:
    """How well the trajectories of a trial match the true markers.

    Attributes
    ----------
    n_trajectories, n_true_markers : int
    matched : dict
        Trajectory label -> true marker it follows (by most of its measured samples).
    correctly_labelled : int
        Trajectories whose label is the name of the marker they follow.
    identity_switches : int
        Measured samples nearer another true marker than the trajectory's own.
    rmse_measured_mm, rmse_filled_mm : float
        3D error of measured and of gap-filled samples against the followed marker.
    coverage : float
        Fraction of true marker-fields (the ``truth_seen`` ones: markers that enough
        cameras see to be reconstructed) that a trajectory covers with a measured or
        filled sample within 20 mm.
    """

    n_trajectories: int
    n_true_markers: int
    matched: dict[str, str]
    correctly_labelled: int
    identity_switches: int
    rmse_measured_mm: float
    rmse_filled_mm: float
    coverage: float


def score_trajectories(
    field: NDArray[np.int64],
    label: NDArray[np.str_],
    xyz_mm: NDArray[np.float64],
    status: NDArray[np.str_],
    truth_field: NDArray[np.int64],
    truth_marker: NDArray[np.str_],
    truth_xyz_mm: NDArray[np.float64],
    truth_seen: NDArray[np.bool_],
) -> TrajectoryScore:
    """Score trajectories (long table) against truth (long table, ``truth_seen`` per row)."""
    names = np.unique(truth_marker)
    name_idx = {n: i for i, n in enumerate(names)}
    n_fields = int(max(field.max(initial=0), truth_field.max(initial=0))) + 1
    truth = np.full((n_fields, len(names), 3), np.nan)
    seen = np.zeros((n_fields, len(names)), dtype=bool)
    ti = np.array([name_idx[n] for n in truth_marker])
    truth[truth_field, ti] = truth_xyz_mm
    seen[truth_field, ti] = truth_seen

    # nearest true marker of every trajectory sample
    nearest = np.full(len(field), -1)
    dist = np.full(len(field), np.inf)
    for f in np.unique(field):
        rows = np.flatnonzero(field == f)
        ok = np.all(np.isfinite(truth[f]), axis=1)
        if not ok.any():
            continue
        d, j = cKDTree(truth[f][ok]).query(xyz_mm[rows])
        nearest[rows] = np.flatnonzero(ok)[j]
        dist[rows] = d

    measured = status == "measured"
    matched: dict[str, str] = {}
    switches = 0
    err_m, err_f = [], []
    covered = np.zeros_like(seen)
    for lab in np.unique(label):
        rows = label == lab
        m = rows & measured & (nearest >= 0)
        if not m.any():
            continue
        own = np.bincount(nearest[m], minlength=len(names)).argmax()
        matched[str(lab)] = str(names[own])
        switches += int(np.sum(nearest[m] != own))
        own_truth = truth[field[rows], own]
        e = np.linalg.norm(xyz_mm[rows] - own_truth, axis=1)
        st = status[rows]
        err_m.append(e[(st == "measured") & np.isfinite(e)])
        err_f.append(e[np.char.startswith(st.astype(str), "filled") & np.isfinite(e)])
        good = (st != "predicted") & (e < 20.0)
        covered[field[rows][good], own] = True
    em = np.concatenate(err_m) if err_m else np.zeros(0)
    ef = np.concatenate(err_f) if err_f else np.zeros(0)
    return TrajectoryScore(
        n_trajectories=len(np.unique(label)),
        n_true_markers=len(names),
        matched=matched,
        correctly_labelled=sum(lab == tru for lab, tru in matched.items()),
        identity_switches=switches,
        rmse_measured_mm=float(np.sqrt(np.mean(em**2))) if len(em) else float("nan"),
        rmse_filled_mm=float(np.sqrt(np.mean(ef**2))) if len(ef) else float("nan"),
        coverage=float(covered[seen].mean()) if seen.any() else float("nan"),
    )


def stick_length_error(
    field: NDArray[np.int64],
    label: NDArray[np.str_],
    xyz_mm: NDArray[np.float64],
    status: NDArray[np.str_],
) -> tuple[float, float, int]:
    """Seed 003, 5.1: mean absolute error and SD of the stick length (mm), and samples.

    The two longest trajectories are the stick's markers; only fields where both are
    measured count.
    """
    labels, counts = np.unique(label[status == "measured"], return_counts=True)
    if len(labels) < 2:
        return float("nan"), float("nan"), 0

    def measured(name: str) -> dict:
        rows = (label == name) & (status == "measured")
        return dict(zip(field[rows], xyz_mm[rows], strict=True))

    fa, fb = (measured(name) for name in labels[np.argsort(counts)[-2:]])
    common = sorted(set(fa) & set(fb))
    length = np.array([np.linalg.norm(fa[f] - fb[f]) for f in common])
    err = length - STICK_LENGTH_MM
    return float(np.mean(np.abs(err))), float(np.std(err)), len(common)


def thrown_gravity(field: NDArray[np.int64], xyz_mm: NDArray[np.float64], rate_hz: float) -> float:
    """Seed 003, 5.1: vertical acceleration (m/s^2) of a parabola fitted to z(t)."""
    t = np.asarray(field, dtype=float) / rate_hz
    return float(-2.0 * np.polyfit(t, xyz_mm[:, 2], 2)[0] / 1000.0)
