"""Every default of the known-target calibration, in one frozen dataclass."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

from kisscal.params import Params, param


@dataclass(frozen=True)
class TargetParams(Params):
    """Parameters of dot finding and target matching (``[target]`` in ``session.toml``).

    Attributes
    ----------
    dots : {"auto", "dark", "bright"}
        Dots darker or lighter than the plate; ``auto`` takes the kind whose dots lie
        nearest the clicked seeds (a click a few pixels off a large dot's centre counts).
    window_px : int
        Side (px, odd) of the neighbourhood whose mean a pixel is compared with (uneven
        light); at least twice a dot's diameter.
    contrast : float
        Grey levels by which a dot pixel must differ from its neighbourhood's mean.
    min_area_px, max_area_px : int
        Size limits of a dot's image (pixels).
    min_fill : float
        Least fraction of its bounding box a dot fills (an ellipse fills pi/4).
    gate : float
        A target point matches the nearest dot within this fraction of its distance to
        the nearest other target point in the image.
    ambiguity : float
        ... and only when the second-nearest dot is at least this many times farther.
    max_iterations : int
        Rounds of project, match and refit.
    seed_tol_px : float
        Largest RMS residual (px) of the clicked seeds under one camera model; beyond it
        the seeds contradict each other and the calibration is refused.
    outlier_px, outlier_sigmas : float
        A match whose dot lies farther from the point's projection than ``outlier_px``
        or ``outlier_sigmas`` times the matches' robust spread (1.4826 x median),
        whichever is larger, is dropped (a speck or a fragment of a dot beside it).
    max_rms_px : float
        Largest RMS residual (px) of the matched dots under the final camera; beyond it
        the matches belong to no camera (seeds that fix the camera badly) and are refused.
    min_matched : float
        Least fraction of the target points inside the image with a dot near their image
        that must match (points hidden behind something have none).
    lens_terms : tuple of str
        Brown lens terms that may be fitted once the points are matched; each is kept
        only when it lowers the held-out reprojection error (see ``min_gain``).
    min_gain : float
        Least fraction by which a term (principal point, pixel aspect, a lens term) must
        lower the leave-one-point-out reprojection error to be kept.
    holdout_step : int
        Every ``holdout_step``-th matched point is left out for the held-out 3D check.
    """

    section: ClassVar[str] = "target"

    dots: Literal["auto", "dark", "bright"] = param("auto")
    window_px: int = param(61, unit="px", ge=3, odd=True)
    contrast: float = param(12.0, gt=0)
    min_area_px: int = param(6, unit="px", ge=1)
    max_area_px: int = param(5000, unit="px", ge=1)
    min_fill: float = param(0.5, gt=0, le=1)
    gate: float = param(0.3, gt=0, lt=0.5)
    ambiguity: float = param(2.0, ge=1)
    max_iterations: int = param(10, ge=1)
    seed_tol_px: float = param(3.0, unit="px", gt=0)
    outlier_px: float = param(1.0, unit="px", gt=0)
    outlier_sigmas: float = param(5.0, gt=0)
    max_rms_px: float = param(2.0, unit="px", gt=0)
    min_matched: float = param(0.5, gt=0, le=1)
    lens_terms: tuple[Literal["k1", "k2", "p1", "p2", "k3"], ...] = param(("k1", "k2", "p1", "p2"))
    min_gain: float = param(0.02, ge=0, lt=1)
    holdout_step: int = param(5, ge=2)


DEFAULT_PARAMS = TargetParams()
