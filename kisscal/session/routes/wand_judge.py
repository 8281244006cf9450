"""Whether the wand route keeps the wand's calibration or the rods' (``kept``).

Both calibrations are judged on points neither was fitted to, on equal footing:

* **Held-out rod markers** (decides): every ``judge_folds``-th marker of each rod is left
  out in turn; the rods' calibration (the rods route's own model) is fitted on the other
  markers, the wand's adjusted again with them as control points, and each left-out
  marker is reconstructed by both (paired: the marker's own image noise is common to
  both). Markers are held out between calibrated ones, so neither calibration
  extrapolates: leave-one-rod-out instead compares the wand against rods-alone cameras
  fitted to one rod fewer (a quarter of the volume gone), which favours the wand
  whatever it does to the lab frame, and the wand's length cannot see a shift or turn of
  the frame at all. The wand is kept only when its squared errors are lower on average.
* **Held-out wand length** (guard): the wand fields left out of the adjustment, measured
  by both; a wand whose length errors are higher by ``keep_sigmas`` standard errors of
  the paired difference is not kept (a scale the rods do not fix well).

Leave-one-rod-out stays in ``check.json`` as a figure, not a judge.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kisscal.bundle.params import BundleParams
from kisscal.bundle.quality import leave_control_out
from kisscal.bundle.wand import WandCalibration
from kisscal.dlt.check import leave_folds_out
from kisscal.dlt.params import DltParams, Rod
from kisscal.dlt.rig import RodCalibration


def held_out_markers(
    cal: WandCalibration,
    rod_cal: RodCalibration,
    rods: Sequence[Rod],
    ids: Sequence[str],
    markers_mm: Sequence[float],
    dlt: DltParams,
    params: BundleParams,
) -> dict[str, Any]:
    """Held-out rod markers reconstructed by both calibrations (see the module).

    Parameters
    ----------
    cal : WandCalibration
        On the rods (with control points).
    rod_cal : RodCalibration
        The rods alone, with their model choice.
    rods : sequence of Rod
    ids : sequence of str
        Camera ids, in the order of ``cal.cameras``.
    markers_mm : sequence of float
        The wand's markers.
    dlt : DltParams
        The session's ``[dlt]`` parameters (the rods' chosen model is applied to them).
    params : BundleParams
        The adjustment's parameters (``judge_folds``).

    Returns
    -------
    dict
        RMS 3D error (mm) of each calibration over the markers both reconstructed, the
        mean paired difference of their squared errors (mm², negative: the wand's lower),
        its standard error and the number of markers; ``{"markers": 0}`` when none.
    """
    n_markers = max(len(r.points_mm) for r in rods)
    truth = np.full((len(rods), n_markers, 3), np.nan)
    for i, rod in enumerate(rods):
        truth[i, : len(rod.points_mm)] = rod.points_mm
    fold = np.tile(np.arange(n_markers) % params.judge_folds, (len(rods), 1))
    fold[~np.isfinite(truth).all(axis=-1)] = -1
    if rod_cal.models is not None:
        dlt = rod_cal.models.params(dlt)
    muv = np.stack([rod_cal.marker_uv_px[c] for c in ids])
    rods_err = leave_folds_out(muv, rods, fold, dlt, ids).ravel()
    flat = truth.reshape(-1, 3)
    row = _marker_of(cal.control.xyz_mm, flat)
    xyz, _, err = leave_control_out(cal, markers_mm, fold.ravel()[row], params)
    wand_err = np.full(len(flat), np.nan)
    wand_err[_marker_of(xyz, flat)] = err
    return paired_errors(wand_err, rods_err)


def _marker_of(xyz_mm: NDArray[np.float64], truth: NDArray[np.float64]) -> NDArray[np.int64]:
    """Index into ``truth`` (rows may be NaN) of each surveyed point in ``xyz_mm``."""
    d = np.linalg.norm(xyz_mm[:, None, :] - truth[None, :, :], axis=-1)
    return np.argmin(np.where(np.isfinite(d), d, np.inf), axis=1)


def paired_errors(wand_mm: NDArray[np.float64], rods_mm: NDArray[np.float64]) -> dict[str, Any]:
    """Paired comparison of two calibrations' 3D errors (mm) on the same points."""
    ok = np.isfinite(wand_mm) & np.isfinite(rods_mm)
    n = int(ok.sum())
    if n < 2:
        return {"markers": n}
    d = wand_mm[ok] ** 2 - rods_mm[ok] ** 2
    return {
        "wand_rms_mm": float(np.sqrt(np.mean(wand_mm[ok] ** 2))),
        "rods_alone_rms_mm": float(np.sqrt(np.mean(rods_mm[ok] ** 2))),
        "mean_difference_mm2": float(np.mean(d)),
        "standard_error_mm2": float(np.std(d, ddof=1) / np.sqrt(n)),
        "markers": n,
    }


def judges(check: dict[str, Any], sigmas: float) -> dict[str, dict[str, Any]]:
    """Each held-out judge's figures for the wand and the rods alone, what it asks of the
    wand (``better`` or ``not worse``) and whether the wand passes."""
    out = {}
    markers = check.get("held_out_rod_markers", {})
    if "mean_difference_mm2" in markers:
        out["held_out_rod_markers_rms_mm"] = {
            "wand": markers["wand_rms_mm"],
            "rods_alone": markers["rods_alone_rms_mm"],
            "asks": "better",
            "wand_passes": bool(markers["mean_difference_mm2"] < 0.0),
        }
    alone = check.get("wand_held_out_rods_alone", {})
    gain = alone.get("wand_minus_rods", {})
    if "mean_difference_mm2" in gain:
        out["held_out_wand_length_rms_error_mm"] = {
            "wand": check["wand_held_out"]["length_rms_error_mm"],
            "rods_alone": alone["length_rms_error_mm"],
            "asks": "not worse",
            "wand_passes": bool(gain["mean_difference_mm2"] <= sigmas * gain["standard_error_mm2"]),
        }
    return out


def kept(check: dict[str, Any]) -> str:
    """``wand`` when the held-out rod markers judge finds it better and no judge finds it
    worse, else ``rods`` (also when the markers could not be judged)."""
    verdicts = check.get("judges", {})
    if "held_out_rod_markers_rms_mm" not in verdicts:
        return "rods"
    return "wand" if all(v["wand_passes"] for v in verdicts.values()) else "rods"
