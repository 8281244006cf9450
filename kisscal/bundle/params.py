"""Every default of the wand calibration (bundle adjustment), in one frozen dataclass."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import ClassVar, Literal

from kisscal.params import Params, param

LensTerm = Literal["k1", "k2", "p1", "p2", "k3"]


@dataclass(frozen=True)
class BundleParams(Params):
    """Parameters of the wand calibration (``[wand]`` keys besides ``trial`` and ``markers_mm``).

    Attributes
    ----------
    lens_terms : tuple of str
        Brown lens terms estimated for every camera (any of ``k1 k2 p1 p2 k3``; empty:
        none). Without a grid they are the whole lens model; with one see ``grid_lens``.
    grid_lens : {"resect", "keep", "brown"}
        Started from the rods' DLTs on a grid's linearisation: ``resect`` holds the
        grid's 30-coefficient polynomial as it is, adjusts each camera as a pinhole with
        skew plus ``lens_terms`` on the linearised pixels (the small correction the
        polynomial left over) and writes each camera as a DLT with ``resect_terms`` of
        Kolahi's terms fitted to the adjusted wand and rod points
        (:mod:`kisscal.bundle.resect`); ``keep`` refines the 11 DLT parameters alone (a
        pinhole with skew, no lens terms); ``brown`` adds ``lens_terms`` (and ``skew`` as
        set) on top of the polynomial, folded into a refitted polynomial afterwards.
    resect_terms : int
        How many of Kolahi's terms L12.. (``[dlt] lens_terms``' order: 3 are the radial
        ones) the written cameras carry with ``grid_lens`` ``resect``.
    skew : bool
        Estimate each camera's skew (non-perpendicular pixel axes). Sensors have none;
        a DLT calibration has it as its eleventh parameter.
    loss : {"soft_l1", "huber", "cauchy", "linear"}
        Robust loss of :func:`scipy.optimize.least_squares` (``linear``: plain least
        squares).
    loss_scale_px : float
        Residual (px) beyond which the robust loss grows slower than the square.
    outlier_px : float
        Observations whose residual after a first adjustment exceeds this (px), or
        ``outlier_sigmas`` times the robust spread, whichever is larger, are dropped and
        the adjustment repeated: markers merged with another spot (an LED ring, a second
        marker behind) have centroids off by a few tenths of a pixel, which would bend
        the calibration if kept.
    outlier_sigmas : float
        See ``outlier_px``.
    tolerance : float
        Relative decrease of the cost below which the adjustment stops.
    max_iterations : int
        Cap on the iterations of one adjustment.
    solver : {"schur", "least_squares"}
        ``schur``: kisscal's sparse Levenberg-Marquardt with the Schur complement and an
        analytic Jacobian (:mod:`kisscal.bundle.solve`); ``least_squares``:
        :func:`scipy.optimize.least_squares` (trust-region reflective, LSMR) with the
        sparse Jacobian pattern and finite differences, the same model and loss. Both reach
        the same minimum; the second takes ten to a hundred times longer on a full trial.
    max_fields : int
        Most wand fields used (evenly spread over the trial); more add time, not accuracy.
    min_fields : int
        Fewest fields in which a camera must see the wand together with another camera.
    line_tol_px : float
        Largest distance (px) of a wand marker image from the line through the others.
    ratio_tol : float
        Largest relative error of the gaps between a wand's marker images against the
        wand's own gaps (perspective makes them differ slightly).
    length_tol : float
        Largest relative difference between the wand length in ``markers_mm`` and the
        length the cameras measure (rods' calibration or axes object); beyond it the
        calibration is refused.
    match_tol_mm : float
        Largest 3D error (mm) of a reconstructed wand marker when the wand is found in 3D.
    holdout_fraction : float
        Fraction of wand fields left out of the adjustment for the held-out wand length
        error (0: none).
    keep_sigmas : float
        On rods, when the rods' cameras carry more lens terms than the wand's, the wand's
        calibration is kept only when its held-out rod markers' squared 3D errors are
        below those of the rods' calibration by more than this many standard errors of
        their mean difference (otherwise, unless they are above by more than as many);
        it is not kept when its held-out wand length errors
        (squared, field by field) are above the rods' on the same fields by more than as
        many (:mod:`kisscal.session.routes.wand_judge`).
    judge_folds : int
        On rods, every ``judge_folds``-th marker of each rod is left out of the wand's
        adjustment in turn and reconstructed by the cameras adjusted without it (the
        rods' calibration leaves its markers out one at a time).
    control_weight : float
        Weight of a control point's (rod marker's) squared residual against a wand
        observation's. 0: their noise variances' inverse ratio, estimated from the rods'
        DLT residuals and the wand's residuals after a first adjustment (rod centroids
        averaged over still frames are several times more precise than a moving wand's,
        and with equal weights thousands of wand images would outvote the surveyed
        markers that fix the lab frame).
    control_weight_factors : tuple of float
        With ``control_weight`` 0 and rods, the estimated weight times each factor is
        tried in turn and the one whose leave-one-rod-out error is lowest kept: the
        residuals' ratio leaves out what the grid's polynomial misses over the wand's
        wider reach, which the left-out rods see.
    """

    section: ClassVar[str] = "wand"

    lens_terms: tuple[LensTerm, ...] = param(("k1", "k2", "p1", "p2"))
    grid_lens: Literal["resect", "keep", "brown"] = param("resect")
    resect_terms: int = param(3, ge=1, le=5)
    skew: bool = param(False)
    loss: Literal["soft_l1", "huber", "cauchy", "linear"] = param("soft_l1")
    loss_scale_px: float = param(0.2, unit="px", gt=0)
    outlier_px: float = param(0.25, unit="px", gt=0)
    outlier_sigmas: float = param(5.0, gt=0)
    tolerance: float = param(1e-7, gt=0, lt=1)
    max_iterations: int = param(100, ge=1)
    solver: Literal["schur", "least_squares"] = param("schur")
    max_fields: int = param(1200, ge=10)
    min_fields: int = param(20, ge=3)
    line_tol_px: float = param(1.5, unit="px", gt=0)
    ratio_tol: float = param(0.12, gt=0, lt=1)
    length_tol: float = param(0.03, gt=0, lt=1)
    match_tol_mm: float = param(15.0, unit="mm", gt=0)
    holdout_fraction: float = param(0.2, ge=0, lt=1)
    keep_sigmas: float = param(2.0, ge=0)
    judge_folds: int = param(3, ge=2)
    control_weight: float = param(0.0, ge=0)
    control_weight_factors: tuple[float, ...] = param((1.0, 10.0, 100.0))

    def on_grid(self) -> BundleParams:
        """The parameters for cameras on a grid's linearisation (see ``grid_lens``)."""
        if self.grid_lens == "brown":
            return self
        if self.grid_lens == "resect":
            return replace(self, skew=True)
        return replace(self, lens_terms=(), skew=True)

    def off_grid(self) -> BundleParams:
        """The parameters for cameras on raw pixels: the Brown terms are the whole lens
        model, never resected."""
        return replace(self, grid_lens="brown") if self.grid_lens == "resect" else self

    def check(self) -> None:
        if len(set(self.lens_terms)) != len(self.lens_terms):
            self.fail(f"lens_terms repeats a term: {', '.join(self.lens_terms)}")


DEFAULT_PARAMS = BundleParams()
