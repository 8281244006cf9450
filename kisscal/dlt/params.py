"""Parameters and results of the DLT stage (frozen dataclasses, every default in one place)."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import as_points
from kisscal.params import Params, param


@dataclass(frozen=True)
class DltParams(Params):
    """Every setting of DLT calibration and rod recognition, with its default and unit.

    Attributes
    ----------
    mdlt : bool
        Enforce Hatze's orthogonality constraint (Kolahi et al. 2007, eq. 10), i.e. a
        zero-skew camera, by the iterative modified DLT (``--mdlt``).
    refine : bool
        Minimise the reprojection error in pixels, started from the linear (or MDLT)
        solution: Woltring & Huiskes' iterative adjustment (``--refine``). With ``mdlt``
        the constraint is kept during refinement.
    lens : bool
        Also estimate Kolahi's lens terms L12..L16 (eq. 2) during refinement (``--lens``);
        implies ``refine``. Off by default: kisscal linearises pixels from the grid first.
    lens_terms : int
        How many of L12..L16, in that order, ``lens`` estimates (the rest stay 0): 1 is
        the one radial term ``L12 r^2``, 3 the radial terms, 5 all of them (with the
        decentring L15, L16).
    select_model : bool
        With none of ``mdlt``, ``refine``, ``lens`` given, choose each camera's model
        (linear DLT, refined, refined with L12..L16) by its held-out control points
        (:mod:`kisscal.dlt.select`); False: the linear DLT.
    trials_bundle : bool
        With rods on the whole rig, the model left to the data and trials of images or
        video in the session: each camera's lens terms are fitted on the rods' markers
        and the trials' markers seen by three cameras or more together, a bundle
        adjustment of the cameras and those markers with the rods fixing the frame and
        scale (:mod:`kisscal.bundle.points`, the wand route's adjustment with ``[wand]``'s
        lens settings), instead of a model chosen on the rods' 24 markers alone: those
        cannot tell which model extrapolates (issue 25: on nine synthetic rigs no judge
        on the rods alone chose within 5 % of the best model on more than four).
    bundle_trials : tuple of str
        The trials (by name) ``trials_bundle`` adjusts with the rods; empty: those the
        session's calibration recorded (``out/dlt/calibration.json``), at its first every
        image or video trial it had but the wand's, so that a walk added later leaves the
        calibration as it was (``kisscal calibrate --refresh`` takes every trial again).
    bundle_rods_weight : float
        In that adjustment, the weight of a rod marker's squared residual against a
        trial marker's, over their estimated noise variance ratio (``[wand]
        control_weight``, when not 0, is used as it is). The ratio of the residuals
        leaves out what the grid's polynomial and the resected terms miss over the
        trials' wider reach, and with its weight alone the trials' markers bend the lens
        terms (issue 25, seed 71: lowcost 0.080/0.095 mm inside/edges against 0.067/0.078
        at 10 times it). The wand route, adjusted with the same trials' markers, weighs
        the wand's images against those markers by the noise their own residuals show
        (Helmert's variance components, :func:`kisscal.bundle.adjust.variance_components`)
        and the rods both by their own component and as this adjustment weighs them,
        keeping the one with the lower leave-one-rod-out error.
    model_folds : int
        Subsets the control points are split into for that choice when they are not
        rods (rods: one rod, and one marker of every rod, out at a time).
    model_margin : float
        Each model's held-out error is weighed by ``1 + model_margin`` per unknown beyond
        the fewest before the comparison (the lens model's 5 extra terms must lower the
        held-out error by 10 % to be chosen).
    model_noise_ses : float
        A model with more unknowns is chosen only when its held-out gain over the best
        of the fewer-unknown models exceeds this many standard errors of that gain (the
        paired per-point differences of squared 3D errors): the one-standard-error rule
        (Hastie et al. 2009); 0 keeps the simpler model only when it is no worse.
    fold_fit_factor : float
        A camera whose fit to a fold's remaining points has an RMS residual this many
        times its fit to all of them (at least ``fold_fit_floor_px``) sits that fold out
        of the comparison: the rest no longer determine it.
    fold_fit_floor_px : float
        Floor of that reference residual, so that nearly exact synthetic points do not
        send cameras out for a few thousandths of a pixel.
    linear_margin : float
        The linear DLT is chosen over the refined one (the same 11 unknowns) only when
        its held-out error is lower by this fraction: the refinement is the
        maximum-likelihood fit under pixel noise (Woltring & Huiskes 1990), and a few
        rods left out cannot tell two fits of the same unknowns apart more finely.
    min_points : int
        Fewest control points accepted per camera (the 11-parameter DLT needs 6).
    min_spread_ratio : float
        Smallest accepted ratio of the control points' least to largest principal spread
        (dimensionless); below it the points count as coplanar and the DLT is undefined.
    max_iterations : int
        Cap on function evaluations of the nonlinear solvers (MDLT, refinement).
    tolerance : float
        Relative convergence tolerance of the nonlinear solvers (scipy ``xtol``/``ftol``).
    rod_line_tol_px : float
        Largest distance (pixels) of a blob from a rod's image line to count as on it.
    rod_fit_tol_px : float
        Largest distance (pixels) along the line between a blob and the rod marker
        position predicted by the 1D projectivity fitted to the rod.
    rod_min_markers : int
        Fewest identified markers for a rod to count as recognised in a camera (with 4
        the projective check has a single degree of freedom; 5 leaves two).
    rod_min_distinct : float
        Smallest accepted projective distinctness of the rod configuration: the RMS
        residual (fraction of the rod length) of the best 1D projectivity that maps all
        markers of one rod onto another rod. Configurations below it are refused as not
        unique (partial views are checked per image, see ``rod_ambiguity_ratio``).
    rod_ambiguity_ratio : float
        An identification is refused as ambiguous when a competing hypothesis with as
        many markers fits within this factor of the best one's residual.
    rods_upright : bool
        Rods appear top-up in every image (the top marker has the smaller ``v``), as for
        an upright camera. Halves the hypotheses; set False for a camera mounted upside down.
    rod_refuse_unlisted : bool
        Refuse a rod image in which the blobs left over after recognition hold a rod-like
        line (at least ``rod_min_markers`` blobs within ``rod_line_tol_px`` of a line,
        roughly parallel to and of the length scale of the recognised rods): a rod hanging
        in the volume but missing from ``[[rods.rod]]``. Set False when the lab
        deliberately hangs extra rods or rod-like objects.
    rod_unlisted_angle_deg : float
        Largest angle (degrees) between such a line and the nearest recognised rod's
        image line for it to count as a rod (image lines of plumb rods converge only
        slowly towards the vertical vanishing point).
    rod_max_chance_blobs : float
        A rod image whose blobs are so dense that a line through two of them passes within
        ``rod_line_tol_px`` of more than this many others by chance (evenly spread over
        their extent: :func:`kisscal.dlt.rods.chance_alignments`) is refused up front:
        chance lines of ``rod_min_markers`` blobs would outnumber the rods, and the search
        grows with the cube of the blob count. 1.5 is about 140 blobs in a 752 x 291
        field, 400 in a 1280 x 1024 image.
    rod_max_lines : int
        A rod image with more distinct candidate lines than this (``rod_min_markers`` or
        more blobs on a line) is refused as too busy; each line costs a projective search
        per rod (about 100 lines in a clean image).
    rod_unlisted_length_ratio : float
        Such a line counts as a rod when its length (px, first to last blob) lies within
        this factor of the recognised rods' image lengths (shortest / ratio to longest
        * ratio); the factor covers depth differences and a hidden end marker.
    """

    section: ClassVar[str] = "dlt"

    mdlt: bool = param(False)
    refine: bool = param(False)
    lens: bool = param(False)
    lens_terms: int = param(5, ge=1, le=5)
    select_model: bool = param(True)
    trials_bundle: bool = param(True)
    bundle_trials: tuple[str, ...] = param(())
    bundle_rods_weight: float = param(10.0, gt=0)
    model_folds: int = param(5, ge=2)
    model_margin: float = param(0.02, ge=0)
    model_noise_ses: float = param(1.0, ge=0)
    fold_fit_factor: float = param(3.0, gt=1)
    fold_fit_floor_px: float = param(0.1, unit="px", gt=0)
    linear_margin: float = param(0.1, ge=0)
    min_points: int = param(6, ge=6)
    min_spread_ratio: float = param(1e-3, gt=0, lt=1)
    max_iterations: int = param(2000, ge=1)
    tolerance: float = param(1e-12, gt=0, lt=1)
    rod_line_tol_px: float = param(1.5, unit="px", gt=0)
    rod_fit_tol_px: float = param(1.5, unit="px", gt=0)
    rod_min_markers: int = param(5, ge=4)
    rod_min_distinct: float = param(0.005, ge=0)
    rod_ambiguity_ratio: float = param(3.0, ge=1)
    rods_upright: bool = param(True)
    rod_refuse_unlisted: bool = param(True)
    rod_unlisted_angle_deg: float = param(15.0, unit="deg", gt=0, le=90)
    rod_unlisted_length_ratio: float = param(2.5, ge=1)
    rod_max_chance_blobs: float = param(1.5, gt=0)
    rod_max_lines: int = param(1000, ge=1)

    @property
    def selects(self) -> bool:
        """True when each camera's model is chosen from the data (no switch given)."""
        return self.select_model and not (self.mdlt or self.refine or self.lens)

    @property
    def method(self) -> str:
        """The method name written to ``out/dlt/<camera>.json``: dlt, mdlt or refined."""
        if self.refine or self.lens:
            return "refined"
        return "mdlt" if self.mdlt else "dlt"


@dataclass(frozen=True)
class DltResult:
    """One camera's calibration.

    Attributes
    ----------
    L : ndarray, shape (11,)
        DLT parameters L1..L11 mapping lab mm to (linearised) pixels.
    method : str
        ``"dlt"``, ``"mdlt"`` or ``"refined"``.
    lens : ndarray, shape (5,) or None
        Kolahi's L12..L16 (pixel units, eq. 2, radial in square pixels: see
        :func:`kisscal.dlt.nonlinear.lens_offsets`) when estimated, else None.
    residuals_px : ndarray, shape (N, 2)
        Per control point ``(du, dv)`` = observed - projected, pixels (after the lens
        correction when ``lens`` is set).
    rms_px : float
        sqrt(mean(du^2 + dv^2)): RMS Euclidean reprojection distance in pixels.
    constraint_linear : float
        Relative violation of Hatze's constraint by the linear DLT solution.
    constraint : float
        Relative violation of Hatze's constraint by ``L`` (see
        :func:`kisscal.dlt.camera.hatze_violation`).
    K, R : ndarray, shape (3, 3)
        Intrinsic matrix (``K[2, 2] = 1``) and rotation (``x_cam = R (X - centre)``).
    centre_mm : ndarray, shape (3,)
        Projection centre in lab mm.
    iterations : int
        Function evaluations used by the nonlinear solver (0 for the linear DLT).
    """

    L: NDArray[np.float64]
    method: str
    lens: NDArray[np.float64] | None
    residuals_px: NDArray[np.float64]
    rms_px: float
    constraint_linear: float
    constraint: float
    K: NDArray[np.float64]
    R: NDArray[np.float64]
    centre_mm: NDArray[np.float64]
    iterations: int = 0


def marker_label(rod: str, index: int) -> str:
    """Name of a rod marker: ``"R1.1"`` is the top marker of rod R1 (``index`` 0-based)."""
    return f"{rod}.{index + 1}"


@dataclass(frozen=True)
class Rod:
    """One calibration rod: its name and surveyed marker centres, top to bottom (mm)."""

    name: str
    points_mm: NDArray[np.float64]


def rod_markers(rods: Sequence[Rod]) -> NDArray[np.float64]:
    """The rods' markers, shape (n_rods, n_markers, 3), NaN past a shorter rod's end."""
    truth = np.full((len(rods), max(len(r.points_mm) for r in rods), 3), np.nan)
    for i, rod in enumerate(rods):
        truth[i, : len(rod.points_mm)] = rod.points_mm
    return truth


@dataclass(frozen=True)
class RodMatch:
    """Rod markers identified among one camera's blobs.

    Attributes
    ----------
    camera : str
        Camera id (for messages).
    rod_names : tuple of str
        The rods, in configuration order.
    blob_index : ndarray of int, shape (n_rods, n_markers)
        Index into the blob array of each rod marker, -1 where it was not found.
    fit_rms_px : ndarray, shape (n_rods,)
        RMS distance (px) along each rod's line between blobs and the fitted 1D
        projectivity; NaN for rods not recognised.
    missing : tuple of str
        Markers not found, as ``"R1.4"`` (see :func:`marker_label`: rod R1, fourth marker
        from the top).
    unused_blobs : ndarray of int
        Blobs not assigned to any rod (strobes, noise).
    """

    camera: str
    rod_names: tuple[str, ...]
    blob_index: NDArray[np.int64]
    fit_rms_px: NDArray[np.float64]
    missing: tuple[str, ...]
    unused_blobs: NDArray[np.int64]

    def marker_uv(self, uv_px: NDArray[np.float64]) -> NDArray[np.float64]:
        """Pixel coordinates per rod marker, shape (n_rods, n_markers, 2), NaN if not found."""
        uv = as_points(uv_px, 2, "uv_px")
        out = np.full((*self.blob_index.shape, 2), np.nan)
        found = self.blob_index >= 0
        out[found] = uv[self.blob_index[found]]
        return out

    def control_points(
        self, uv_px: NDArray[np.float64], rods: tuple[Rod, ...]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], tuple[str, ...]]:
        """Return ``(xyz_mm (M, 3), uv_px (M, 2), labels)`` of the identified markers."""
        xyz = np.concatenate([r.points_mm for r in rods])
        idx = self.blob_index.ravel()
        found = idx >= 0
        labels = tuple(marker_label(r.name, i) for r in rods for i in range(len(r.points_mm)))
        uv = np.asarray(uv_px, dtype=float)[idx[found]]
        return xyz[found], uv, tuple(lab for lab, f in zip(labels, found, strict=True) if f)


@dataclass(frozen=True)
class RodCheck:
    """Leave-one-rod-out check: calibrate on the other rods, reconstruct the left-out one.

    Attributes
    ----------
    rod_names : tuple of str
        Left-out rod of each row.
    mean_mm, max_mm : ndarray, shape (n_rods,)
        Mean and largest 3D error (mm) of the left-out rod's reconstructed markers.
    n_markers : ndarray of int, shape (n_rods,)
        Markers of the left-out rod seen by at least two cameras.
    errors_mm : ndarray, shape (n_rods, n_markers)
        Per marker 3D error, NaN where not reconstructed.
    """

    rod_names: tuple[str, ...]
    mean_mm: NDArray[np.float64]
    max_mm: NDArray[np.float64]
    n_markers: NDArray[np.int64]
    errors_mm: NDArray[np.float64]

    @classmethod
    def of(cls, rods: Sequence[Rod], errors_mm: NDArray[np.float64]) -> RodCheck:
        """The check of ``rods`` whose markers' 3D errors are ``errors_mm`` (NaN where a
        marker was not reconstructed)."""
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a rod no two cameras saw
            mean, worst = np.nanmean(errors_mm, axis=1), np.nanmax(errors_mm, axis=1)
        found = np.isfinite(errors_mm).sum(axis=1)
        return cls(tuple(r.name for r in rods), mean, worst, found, errors_mm)

    @property
    def overall_mean_mm(self) -> float:
        """Mean 3D error over every reconstructed left-out marker (mm)."""
        return float(np.nanmean(self.errors_mm))

    @property
    def overall_max_mm(self) -> float:
        """Largest 3D error over every reconstructed left-out marker (mm)."""
        return float(np.nanmax(self.errors_mm))


DEFAULT_PARAMS = DltParams()
"""The defaults, shared as a module-level constant (frozen, so safe as an argument default)."""
