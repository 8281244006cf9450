"""Which camera model the control points support: chosen by held-out points.

A technician cannot judge whether a lens needs Kolahi's L12..L16 (Kolahi et al. 2007, eqs.
2-3), or only his radial term L12, on top of the grid's linearisation, or whether the
pixel refinement of Woltring & Huiskes (1990) helps: a model with more terms always fits
its own points better. So each candidate model is fitted with some control points left out
and judged by how well the rig then reconstructs them (cross-validation, Stone 1974). For
other control points, each of ``model_folds`` interleaved subsets is left out in turn. The
rods are left out by two designs, and a model's held-out error is the geometric mean of
the two RMS errors, so that it must do well in both: one rod at a time (how the model
reaches into the corner a missing rod leaves), and one marker of every rod at a time, at a
different height on each (:func:`staggered_folds`: how it does between the other markers).
Either design alone misleads on some synthetic rigs: leaving rods out judges only the
reach into an empty corner, where the 16-unknown lens model does no better than one radial
term on a rig where it is three times better inside the volume; leaving markers out ranks
it first on a rig where it bends the volume between the rods. The model
whose held-out 3D error is smallest is chosen for every camera, after weighing each model's
error by ``1 + model_margin`` per unknown beyond the fewest, and the linear DLT's by
``1 + linear_margin`` against the refined one (the maximum-likelihood fit of the same
unknowns under pixel noise, which held-out points cannot tell apart from it more finely),
before the comparison (more terms must earn their keep). The best weighed model is then
chosen only if its held-out gain over the best model with fewer unknowns exceeds
``model_noise_ses`` standard errors of that gain (the per-point differences of squared 3D
errors, paired across the models): the one-standard-error rule of Hastie, Tibshirani &
Friedman (2009, sect. 7.10), walked up from the fewest unknowns. On the real cavity target
the radial term was 2.5 % ahead of the refined DLT on the even dots, a gain of 0.98 of its
standard error (31 points), and did worse than it on the odd dots. A camera whose fit to
a fold's remaining points is ``fold_fit_factor`` times worse than its fit to all of them
sits that fold out instead of poisoning it: the rest no longer determine it (on the cavity
target, a near-flat plate of three depth levels, one interleaved fold takes most of a
level from two cameras, and their undetermined DLTs made the linear model's held-out
error 1.6 mm where the other half of the dots measures 0.12 mm). Each camera's held-out
reprojection error under every model (the quadratic mean over the designs) is
kept beside it, for the report.

With a single camera (``--camera``) no point can be reconstructed; the held-out
reprojection error of that camera decides instead.

References
----------
Hastie, T., Tibshirani, R., & Friedman, J. (2009). The Elements of Statistical Learning,
2nd ed. Springer (sect. 7.10, the one-standard-error rule).
Stone, M. (1974). Cross-validatory choice and assessment of statistical predictions.
Journal of the Royal Statistical Society B 36(2), 111-147.
Kolahi, A., et al. (2007). Design of a marker-based human motion tracking system.
Biomedical Signal Processing and Control 2, 59-67.
Woltring, H. J., & Huiskes, R. (1990). Stereophotogrammetry. In Biomechanics of Human
Movement (Berme & Cappozzo, eds.).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.calibrate import calibrate_camera
from kisscal.dlt.linear import reprojection_residuals
from kisscal.dlt.nonlinear import correct_lens
from kisscal.dlt.params import DEFAULT_PARAMS, DltParams
from kisscal.dlt.triangulate import triangulate_observations
from kisscal.errors import KisscalError

#: The candidate models, simplest first: name -> the DLT switches that fit it.
MODELS: dict[str, dict[str, bool | int]] = {
    "dlt": {"mdlt": False, "refine": False, "lens": False, "lens_terms": 5},
    "refined": {"mdlt": False, "refine": True, "lens": False, "lens_terms": 5},
    "radial": {"mdlt": False, "refine": True, "lens": True, "lens_terms": 1},
    "lens": {"mdlt": False, "refine": True, "lens": True, "lens_terms": 5},
}

#: Unknowns of each model per camera: a model's held-out error is weighed by
#: ``1 + model_margin * (its unknowns - the fewest)`` before the comparison.
MODEL_UNKNOWNS: dict[str, int] = {"dlt": 11, "refined": 11, "radial": 12, "lens": 16}

#: What each model is, in words (report tables).
MODEL_NAMES: dict[str, str] = {
    "dlt": "linear DLT (11 parameters)",
    "refined": "DLT refined in pixels",
    "radial": "DLT + L12 (one radial term)",
    "lens": "DLT + L12-L16 lens terms",
}


@dataclass(frozen=True)
class CameraPoints:
    """One camera's control points for the comparison.

    Attributes
    ----------
    xyz_mm : ndarray, shape (M, 3)
    uv_px : ndarray, shape (M, 2)
        In the coordinates the DLT maps to (grid-linearised when there is a grid).
    point : ndarray of int, shape (M,)
        Each row's point id, shared by the cameras (the same rod marker, target dot).
    """

    xyz_mm: NDArray[np.float64]
    uv_px: NDArray[np.float64]
    point: NDArray[np.int64]


@dataclass(frozen=True)
class ModelChoice:
    """The camera models compared on held-out control points.

    Attributes
    ----------
    chosen : str
        The key of :data:`MODELS` chosen for every camera.
    held_out_3d_mm : dict
        Model -> RMS 3D error (mm) of the held-out points the rig reconstructed, the
        geometric mean over the fold designs when there are several (inf with a single
        camera, or when some camera cannot carry the model).
    held_out_3d_mean_mm, held_out_3d_max_mm : dict
        Model -> mean and largest of those errors (mm).
    held_out_px : dict
        Camera -> model -> RMS reprojection error (px) of that camera's held-out points;
        inf for every camera where the model could not fit some camera's points (it is
        not chosen, and its folds are not fitted).
    in_sample_px : dict
        Camera -> model -> RMS residual (px) of the fit to all its points.
    folds : int
        How many subsets were left out in turn.
    points : int
        Held-out points the chosen model's rig reconstructed.
    by : str
        What decided: ``"held-out 3D error"`` or ``"held-out reprojection error"``.
    """

    chosen: str
    held_out_3d_mm: dict[str, float]
    held_out_3d_mean_mm: dict[str, float]
    held_out_3d_max_mm: dict[str, float]
    held_out_px: dict[str, dict[str, float]]
    in_sample_px: dict[str, dict[str, float]]
    folds: int
    points: int
    by: str

    def params(self, base: DltParams) -> DltParams:
        """``base`` with the switches of the chosen model."""
        return replace(base, **MODELS[self.chosen])

    def camera_dict(self, camera: str) -> dict:
        """JSON-ready comparison for ``dlt/<camera>.json`` (``lens_models``)."""
        return {
            "chosen": self.chosen,
            "by": self.by,
            "folds": self.folds,
            "held_out_points": self.points,
            "models": {
                m: {
                    "model": MODEL_NAMES[m],
                    "held_out_3d_rms_mm": _finite(self.held_out_3d_mm[m]),
                    "held_out_rms_px": _finite(self.held_out_px[camera][m]),
                    "in_sample_rms_px": _finite(self.in_sample_px[camera][m]),
                }
                for m in self.held_out_3d_mm
            },
        }

    def rig_dict(self) -> dict:
        """JSON-ready choice for the rig's figures (``summary.json``, ``check.json``)."""
        rms = {m: _finite(v) for m, v in self.held_out_3d_mm.items()}
        return {"chosen": self.chosen, "by": self.by, "held_out_3d_rms_mm": rms}


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def interleaved_folds(ids: NDArray[np.int64], folds: int) -> NDArray[np.int64]:
    """Fold of each point id: the sorted ids dealt out in turn (spread evenly)."""
    _, rank = np.unique(ids, return_inverse=True)
    return rank.ravel() % max(1, folds)


def staggered_folds(
    group: NDArray[np.int64], index: NDArray[np.int64], folds: int
) -> NDArray[np.int64]:
    """Fold of each point given its group (rod) and place in it (marker): a Latin square.

    Fold ``f`` holds the marker ``(f - rod) mod folds`` of every rod: one marker of each
    rod, at a different height on each, so every fold leaves points out from inside the
    span of the rest (the top and bottom of the volume stay covered by the other rods)
    rather than a whole corner of the volume.
    """
    return (np.asarray(index) + np.asarray(group)) % max(1, folds)


def choose_model(
    cameras: Mapping[str, CameraPoints],
    fold_of_point: NDArray[np.int64],
    params: DltParams = DEFAULT_PARAMS,
    candidates: Sequence[str] = tuple(MODELS),
) -> ModelChoice:
    """Compare :data:`MODELS` by leaving each fold of points out in turn.

    Parameters
    ----------
    cameras : mapping
        Camera id -> its control points.
    fold_of_point : ndarray of int, shape (n_ids,) or (n_designs, n_ids)
        Fold of each point id (:func:`interleaved_folds`), or one row per fold design
        (the rods: its rod, and :func:`staggered_folds`); each design is run in turn and
        a model's held-out 3D error is the geometric mean of the designs' RMS errors.
    params : DltParams
        Tolerances (the switches are set per model) and ``model_margin``.
    candidates : sequence of str
        The models compared (keys of :data:`MODELS`, simplest first).

    Returns
    -------
    ModelChoice
    """
    designs = np.atleast_2d(np.asarray(fold_of_point))
    held_3d, mean_3d, max_3d, held_px, inside, counts, squared = {}, {}, {}, {}, {}, {}, {}
    for name in candidates:
        p = replace(params, **MODELS[name])
        for cam in cameras:
            inside.setdefault(cam, {})[name] = _in_sample(cameras[cam], p, cam)
        full = {c: inside[c][name] for c in cameras}
        carried = all(np.isfinite(inside[c][name]) for c in cameras)  # every camera or none
        # a model that cannot fit every camera's points is not chosen: no folds for it
        # (on the real cavity target, Brown's five terms failed on two cameras and their
        # folds took two thirds of the comparison's time)
        runs = [_cross_validate(cameras, d, p, full) for d in designs] if carried else []
        for cam in cameras:
            rms_px = [per_camera[cam] for *_, per_camera in runs] or [np.inf]
            # the designs' quadratic mean
            held_px.setdefault(cam, {})[name] = float(np.sqrt(np.mean(np.square(rms_px))))
        ok = carried and all(len(e) > 0 for _, e, _ in runs)
        every = np.concatenate([e for _, e, _ in runs] or [np.zeros(0)])
        rms = [float(np.sqrt(np.mean(e**2))) for _, e, _ in runs] if ok else [np.inf]
        held_3d[name] = float(np.exp(np.mean(np.log(rms))))  # geometric mean of designs
        mean_3d[name] = float(np.mean(every)) if ok else np.inf
        max_3d[name] = float(np.max(every)) if ok else np.inf
        counts[name] = len(every)
        # each held-out point once per design: key design * (ids) + id, to pair models
        span = designs.shape[1]
        squared[name] = (
            np.concatenate(
                [k * span + i for k, (i, _, _) in enumerate(runs)] or [np.zeros(0, int)]
            ),
            every**2,
        )
    three_d = len(cameras) >= 2 and any(np.isfinite(v) for v in held_3d.values())
    if three_d:
        score = held_3d
    else:  # one camera: its own held-out reprojection error
        score = {m: float(np.mean([held_px[c][m] for c in cameras])) for m in candidates}
    fewest = min(MODEL_UNKNOWNS[m] for m in candidates)
    weighed = {
        m: score[m]
        * (1.0 + params.model_margin * (MODEL_UNKNOWNS[m] - fewest))
        * (1.0 + (params.linear_margin if m == "dlt" and "refined" in candidates else 0.0))
        for m in candidates
    }
    chosen = _simplest_within_noise(
        candidates, weighed, squared, params.model_noise_ses if three_d else None
    )
    by = "held-out 3D error" if three_d else "held-out reprojection error"
    folds = sum(len(np.unique(d)) for d in designs)
    return ModelChoice(chosen, held_3d, mean_3d, max_3d, held_px, inside, folds, counts[chosen], by)


def _simplest_within_noise(
    candidates: Sequence[str],
    weighed: Mapping[str, float],
    squared: Mapping[str, tuple[NDArray[np.int64], NDArray[np.float64]]],
    ses: float | None,
) -> str:
    """The model with the fewest unknowns whose held-out error is not worse than the
    best's by more than ``ses`` standard errors (the one-standard-error rule of Hastie,
    Tibshirani & Friedman 2009, sect. 7.10, on the paired per-point differences of the
    squared 3D errors); among models of equally many unknowns, the best weighed one.
    ``ses`` None: the best weighed model."""
    finite = [m for m in candidates if np.isfinite(weighed[m])]
    if not finite:
        return candidates[0]
    best = min(finite, key=weighed.__getitem__)  # the first of equals: the simplest
    if ses is None:
        return best
    for most in sorted({MODEL_UNKNOWNS[m] for m in finite}):
        simple = min((m for m in finite if MODEL_UNKNOWNS[m] <= most), key=weighed.__getitem__)
        if simple == best or _not_worse(squared[simple], squared[best], ses):
            return simple
    return best


def _not_worse(
    simple: tuple[NDArray[np.int64], NDArray[np.float64]],
    rich: tuple[NDArray[np.int64], NDArray[np.float64]],
    ses: float,
) -> bool:
    """True when the richer model's mean gain in squared error over the points both
    reconstructed is at most ``ses`` standard errors of that gain: within its noise."""
    _, a, b = np.intersect1d(simple[0], rich[0], assume_unique=True, return_indices=True)
    if len(a) < 2:
        return False
    gain = simple[1][a] - rich[1][b]
    return bool(np.mean(gain) <= ses * np.std(gain, ddof=1) / np.sqrt(len(gain)))


def _in_sample(points: CameraPoints, params: DltParams, camera: str) -> float:
    try:
        return calibrate_camera(points.xyz_mm, points.uv_px, params, camera).rms_px
    except KisscalError:
        return np.inf


def _cross_validate(
    cameras: Mapping[str, CameraPoints],
    fold_of_point: NDArray[np.int64],
    params: DltParams,
    full_px: Mapping[str, float],
) -> tuple[NDArray[np.int64], NDArray[np.float64], dict[str, float]]:
    """Ids and 3D errors (mm) of every fold's points reconstructed by cameras fitted
    without them, and each camera's held-out reprojection RMS (px). A camera whose fit to the
    rest is ``fold_fit_factor`` times worse than ``full_px`` (its fit to all) sits the
    fold out."""
    ids = list(cameras)
    residuals: dict[str, list[NDArray]] = {c: [] for c in ids}
    errors = []
    for g in np.unique(fold_of_point):
        Ls, rows_cam, rows_pt, rows_uv = [], [], [], []
        truth = {}
        for cam in ids:
            pts = cameras[cam]
            test = fold_of_point[pts.point] == g
            try:
                fit = calibrate_camera(pts.xyz_mm[~test], pts.uv_px[~test], params, cam)
            except KisscalError:  # the rest too few or too flat: this fold goes without
                continue
            if fit.rms_px > params.fold_fit_factor * max(full_px[cam], params.fold_fit_floor_px):
                continue  # the rest no longer determine this camera's model
            seen = correct_lens(fit.L, fit.lens, pts.uv_px[test])
            residuals[cam].append(reprojection_residuals(fit.L, pts.xyz_mm[test], seen))
            rows_cam.append(np.full(int(test.sum()), len(Ls)))
            rows_pt.append(pts.point[test])
            rows_uv.append(seen)
            truth.update(zip(pts.point[test].tolist(), pts.xyz_mm[test], strict=True))
            Ls.append(fit.L)
        errors.append(_fold_errors(Ls, rows_cam, rows_pt, rows_uv, truth))
    px = {c: _rms(residuals[c]) for c in ids}
    if not errors:
        return np.zeros(0, dtype=np.int64), np.zeros(0), px
    return np.concatenate([i for i, _ in errors]), np.concatenate([e for _, e in errors]), px


def _fold_errors(
    Ls: list, rows_cam: list, rows_pt: list, rows_uv: list, truth: dict
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Ids and 3D errors (mm) of one fold's points seen by two or more of its cameras."""
    none = (np.zeros(0, dtype=np.int64), np.zeros(0))
    if len(Ls) < 2:
        return none
    cam = np.concatenate(rows_cam)
    ids, point = np.unique(np.concatenate(rows_pt), return_inverse=True)
    point = point.ravel()
    enough = np.bincount(point, minlength=len(ids)) >= 2
    if not enough.any():
        return none
    tri = triangulate_observations(np.array(Ls), point, cam, np.concatenate(rows_uv), len(ids))
    true = np.array([truth[i] for i in ids.tolist()])
    err = np.linalg.norm(tri.xyz_mm - true, axis=1)
    keep = enough & np.isfinite(err)
    return ids[keep].astype(np.int64), err[keep]


def _rms(rows: list[NDArray]) -> float:
    r = np.concatenate(rows) if rows else np.zeros((0, 2))
    return float(np.sqrt(np.mean(np.sum(r**2, axis=1)))) if len(r) else np.inf
