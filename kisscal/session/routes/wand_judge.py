"""Whether the wand route keeps the wand's calibration or the rods' (``kept``).

Both calibrations are judged on points neither was fitted to, on equal footing:

* **Held-out rod markers** (decides): each rod marker is reconstructed by both
  calibrations fitted without it (paired: the marker's own image noise is common to both).
  The rods' calibration (the rods route's own model) is refitted without one marker at a
  time (leave one out), the wand's adjusted again without every ``judge_folds``-th marker
  of each rod in turn. Each side loses as little as it can: refitted without a third of
  its markers, a 16-unknown lens model on four rods of six markers is twice as far off
  as the calibration it stands for (synthetic kiss rig, seed 46: 0.055 mm held out
  against 0.024 mm from the true cameras at the same markers, 0.045 mm left out one by
  one), while the wand, held by thousands of wand images, hardly notices (0.042 mm, a
  sixth of the markers out 0.044 mm); judged by thirds, the wand looked better there
  when it was worse against the truth (0.031 against 0.017 mm inside the volume).
  Markers are held out between calibrated ones, so neither calibration extrapolates:
  leave-one-rod-out instead compares the wand against rods-alone cameras fitted to one
  rod fewer (a quarter of the volume gone), which favours the wand whatever it does to
  the lab frame, and the wand's length cannot see a shift or turn of the frame at all.
  Even left out one by one, a model with more unknowns loses more, so the burden of
  proof follows the models (:func:`markers_burden`): when the rods' cameras carry more
  lens terms than the wand's written ones (the rods chose L12..L16, the wand writes
  L12..L14), the wand's squared errors must be lower by ``keep_sigmas`` standard errors
  of the paired difference; otherwise they must not be higher by as many. Markers near
  the rods cannot see the middle of the volume, where only the wand goes, and with no
  more lens terms than the wand's the rods' cameras have nothing the wand could not
  follow there, so a tie goes to the wand: on the synthetic modern rig, seed 51, the
  wand is better against the truth (0.0077 against 0.0096 mm inside the volume) while
  the held-out markers find it worse by 1.1 standard errors (0.0106 against 0.0097 mm),
  and on the lowcost rig, seed 44, the rods' pinhole is three times worse in the middle
  (0.098 against 0.031 mm) while the markers find the two alike (half a standard
  error). Checked on six synthetic rigs (kiss 43, 46, 51; lowcost 44, 51; modern 51):
  the route kept the better calibration against the truth on each (kiss 43 has the
  wand better inside the volume, 0.024 against 0.031 mm, and slightly worse at its
  edges, 0.029 against 0.026 mm).
* **Held-out wand length** (guard): the wand fields left out of the adjustment, measured
  by both; a wand whose length errors are higher by ``keep_sigmas`` standard errors of
  the paired difference is not kept (a scale the rods do not fix well).

With trials adjusted with the rods (``[dlt] trials_bundle``, the rods route's default), the
wand is adjusted with the same trials' markers and the rods' calibration to beat is that
default: both are bundle adjustments on the same rods, so both are held out by the same
folds of markers (``baseline`` of :func:`held_out_markers`), and the burden is "not worse"
(both written with ``resect_terms`` of Kolahi's terms).

Leave-one-rod-out stays in ``check.json`` as a figure, not a judge.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from kisscal.bundle.params import BundleParams
from kisscal.bundle.points import POINT
from kisscal.bundle.quality import leave_control_out
from kisscal.bundle.wand import WandCalibration
from kisscal.dlt.check import leave_folds_out
from kisscal.dlt.params import DltParams, Rod, rod_markers
from kisscal.dlt.rig import RodCalibration


def held_out_markers(
    cal: WandCalibration,
    rod_cal: RodCalibration,
    rods: Sequence[Rod],
    ids: Sequence[str],
    markers_mm: Sequence[float],
    dlt: DltParams,
    params: BundleParams,
    baseline: WandCalibration | None = None,
) -> PairedErrors:
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
    baseline : WandCalibration, optional
        The rods and trials adjusted together (:mod:`.trial_bundle`), whose cameras
        ``rod_cal`` holds: then held out as the wand is, by the same folds of markers
        (both adjustments lose the same rods' markers and keep their own rays).

    Returns
    -------
    PairedErrors
        Over the markers both calibrations reconstructed.
    """
    truth = rod_markers(rods)
    fold = np.tile(np.arange(truth.shape[1]) % params.judge_folds, (len(rods), 1))
    fold[~np.isfinite(truth).all(axis=-1)] = -1
    if baseline is not None:
        rods_err = _folds_held_out(baseline, POINT, truth, fold, params)
    else:
        rods_err = rods_held_out(rod_cal, rods, ids, dlt).ravel()
    wand_err = _folds_held_out(cal, markers_mm, truth, fold, params)
    return paired_errors(wand_err, rods_err)


def _folds_held_out(
    cal: WandCalibration,
    markers_mm: Sequence[float],
    truth: NDArray[np.float64],
    fold: NDArray[np.int64],
    params: BundleParams,
) -> NDArray[np.float64]:
    """Each rod marker's 3D error (mm, NaN where not reconstructed) by ``cal`` adjusted
    again without its fold of markers."""
    flat = truth.reshape(-1, 3)
    row = _marker_of(cal.control.xyz_mm, flat)
    xyz, _, err = leave_control_out(cal, markers_mm, fold.ravel()[row], params)
    out = np.full(len(flat), np.nan)
    out[_marker_of(xyz, flat)] = err
    return out


def rods_held_out(
    rod_cal: RodCalibration, rods: Sequence[Rod], ids: Sequence[str], dlt: DltParams
) -> NDArray[np.float64]:
    """Each rod marker's 3D error (mm) when every camera is calibrated without it.

    Parameters
    ----------
    rod_cal : RodCalibration
        The rods alone, with their model choice (applied to ``dlt``).
    rods : sequence of Rod
    ids : sequence of str
        Camera ids.
    dlt : DltParams
        The session's ``[dlt]`` parameters.

    Returns
    -------
    ndarray, shape (n_rods, n_markers)
        NaN where a marker is missing or was not reconstructed.
    """
    truth = rod_markers(rods)
    fold = np.arange(truth.shape[0] * truth.shape[1]).reshape(truth.shape[:2])
    fold[~np.isfinite(truth).all(axis=-1)] = -1
    if rod_cal.models is not None:
        dlt = rod_cal.models.params(dlt)
    muv = np.stack([rod_cal.marker_uv_px[c] for c in ids])
    return leave_folds_out(muv, rods, fold, dlt, ids)


def markers_burden(rod_cal: RodCalibration, wand_terms: int, sigmas: float) -> float:
    """Standard errors by which the wand must beat the rods on the held-out markers.

    Parameters
    ----------
    rod_cal : RodCalibration
        The rods alone (each camera's lens terms, none for a pinhole).
    wand_terms : int
        Kolahi's terms the wand's written cameras carry (0 when not resected).
    sigmas : float
        ``[wand] keep_sigmas``.

    Returns
    -------
    float
        ``sigmas`` when some rods' camera carries more lens terms than ``wand_terms``
        (the wand must be better by as many), else ``-sigmas`` (it must not be worse by
        more than as many).
    """
    lens = [r.lens for r in rod_cal.results.values() if r.lens is not None]
    rods_terms = max((int(np.count_nonzero(t)) for t in lens), default=0)
    return float(sigmas) if rods_terms > wand_terms else -float(sigmas)


def _marker_of(xyz_mm: NDArray[np.float64], truth: NDArray[np.float64]) -> NDArray[np.int64]:
    """Index into ``truth`` (rows may be NaN) of each surveyed point in ``xyz_mm``."""
    d = np.linalg.norm(xyz_mm[:, None, :] - truth[None, :, :], axis=-1)
    return np.argmin(np.where(np.isfinite(d), d, np.inf), axis=1)


@dataclass(frozen=True)
class PairedErrors:
    """Two calibrations' 3D errors on the same held-out points, compared point by point.

    Attributes
    ----------
    markers : int
        Points both calibrations reconstructed (the figures below need two or more).
    wand_rms_mm, rods_alone_rms_mm : float
        RMS 3D error of each (NaN with fewer than two points).
    mean_difference_mm2 : float
        Mean of the wand's squared error minus the rods' (negative: the wand's lower).
    standard_error_mm2 : float
        Its standard error (the points' own noise, common to both, cancels).
    """

    markers: int
    wand_rms_mm: float = float("nan")
    rods_alone_rms_mm: float = float("nan")
    mean_difference_mm2: float = float("nan")
    standard_error_mm2: float = float("nan")

    @property
    def measured(self) -> bool:
        return self.markers >= 2

    def as_dict(self) -> dict[str, Any]:
        """The ``check.json`` group (only ``markers`` when not measured)."""
        return asdict(self) if self.measured else {"markers": self.markers}


def paired_errors(wand_mm: NDArray[np.float64], rods_mm: NDArray[np.float64]) -> PairedErrors:
    """Paired comparison of two calibrations' 3D errors (mm) on the same points."""
    ok = np.isfinite(wand_mm) & np.isfinite(rods_mm)
    n = int(ok.sum())
    if n < 2:
        return PairedErrors(n)
    d = wand_mm[ok] ** 2 - rods_mm[ok] ** 2
    return PairedErrors(
        n,
        float(np.sqrt(np.mean(wand_mm[ok] ** 2))),
        float(np.sqrt(np.mean(rods_mm[ok] ** 2))),
        float(np.mean(d)),
        float(np.std(d, ddof=1) / np.sqrt(n)),
    )


@dataclass(frozen=True)
class Verdict:
    """One held-out judge: both calibrations' figures, what it asks of the wand
    (``better`` or ``not worse``, by ``sigmas`` standard errors of the paired difference)
    and whether the wand passes."""

    wand: float
    rods_alone: float
    asks: Literal["better", "not worse"]
    sigmas: float
    wand_passes: bool


@dataclass(frozen=True)
class LengthEvidence:
    """The held-out wand fields measured by both calibrations.

    Attributes
    ----------
    wand_rms_mm, rods_alone_rms_mm : float
        RMS error of the wand's end-to-end length.
    mean_difference_mm2, standard_error_mm2 : float
        The paired difference of their squared errors and its standard error
        (:func:`kisscal.bundle.quality.paired_length_gain`).
    """

    wand_rms_mm: float
    rods_alone_rms_mm: float
    mean_difference_mm2: float
    standard_error_mm2: float


@dataclass(frozen=True)
class Judgement:
    """The evidence that decides between the wand's calibration and the rods' alone.

    Attributes
    ----------
    markers : PairedErrors
        Held-out rod markers (decides: the wand must be better by more than
        ``better_sigmas`` standard errors; negative, not worse by more than as many).
    length : LengthEvidence or None
        Held-out wand length (guard: the wand must not be worse by more than ``sigmas``
        standard errors), None when not measured.
    sigmas : float
        ``[wand] keep_sigmas``.
    better_sigmas : float
        :func:`markers_burden`.
    """

    markers: PairedErrors
    length: LengthEvidence | None
    sigmas: float
    better_sigmas: float = 0.0

    def verdicts(self) -> dict[str, Verdict]:
        """Each judge that could be measured, by its ``check.json`` name."""
        out = {}
        m = self.markers
        if m.measured:
            b = self.better_sigmas
            passes = bool(m.mean_difference_mm2 < -b * m.standard_error_mm2)
            asks = "better" if b >= 0 else "not worse"
            out["held_out_rod_markers_rms_mm"] = Verdict(
                m.wand_rms_mm, m.rods_alone_rms_mm, asks, abs(b), passes
            )
        g = self.length
        if g is not None:
            fine = bool(g.mean_difference_mm2 <= self.sigmas * g.standard_error_mm2)
            out["held_out_wand_length_rms_error_mm"] = Verdict(
                g.wand_rms_mm, g.rods_alone_rms_mm, "not worse", self.sigmas, fine
            )
        return out

    @property
    def kept(self) -> Literal["wand", "rods"]:
        """``wand`` when the held-out rod markers find it better (by ``better_sigmas``
        standard errors; not worse when negative) and no judge finds it worse, else ``rods``
        (also when the markers could not be judged)."""
        verdicts = self.verdicts()
        if "held_out_rod_markers_rms_mm" not in verdicts:
            return "rods"
        return "wand" if all(v.wand_passes for v in verdicts.values()) else "rods"

    def as_dict(self) -> dict[str, dict[str, Any]]:
        """``check.json``'s ``judges`` group."""
        return {name: asdict(v) for name, v in self.verdicts().items()}


def length_evidence(wand_doc: dict[str, Any]) -> LengthEvidence | None:
    """The held-out wand length figures of ``dlt/wand.json`` (None when not measured)."""
    alone = wand_doc.get("held_out_rods_alone", {})
    gain = alone.get("wand_minus_rods", {})
    if "mean_difference_mm2" not in gain:
        return None
    return LengthEvidence(
        float(wand_doc["held_out"]["length_rms_error_mm"]),
        float(alone["length_rms_error_mm"]),
        float(gain["mean_difference_mm2"]),
        float(gain["standard_error_mm2"]),
    )
