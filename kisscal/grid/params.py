"""Every default of the grid linearisation stage, in one frozen dataclass."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar, Literal

from kisscal.params import Params, param

OptimalModel = Literal["similarity", "homography"]


@dataclass(frozen=True)
class GridParams(Params):
    """Parameters of grid linearisation (Küçük 2005, section 2.2; Shafiq et al. 2001, 3.2).

    Attributes
    ----------
    rows, cols : int
        Dots per column and per row of the linearisation grid (the KISS grid: 15 x 20).
    model : {"homography", "similarity"}
        Transform from the primary grid to the optimal grid. ``"similarity"`` is the thesis'
        eq. 2.1 (scale, rotation, translation), carried out in the square-pixel frame (see
        :func:`kisscal.grid.optimal.optimal_grid`); it assumes the grid square to the camera.
        ``"homography"`` (beyond the seeds, the default) also takes up the perspective of a
        grid tilted a few degrees, which the similarity leaves in the polynomial: 2 px of
        keystone over a 752 x 291 field at 2 degrees of tilt. On a grid square to the camera
        both give the same correction within 0.03 px.
    pixel_aspect : float or None
        Height over width of one pixel as it images the grid (fy / fx, about 0.52 for the
        752 x 291 fields). None: fitted by least squares together with the similarity.
        Only used by the ``"similarity"`` model.
    cell_aspect : float
        Row pitch over column pitch of the physical grid, in mm / mm (1 for square cells).
    min_indexed_fraction : float
        Fewest dots, as a fraction of ``rows * cols``, that must be indexed before fitting.
    match_tol : float
        Largest distance, as a fraction of the local dot spacing, from a predicted lattice
        position to the dot accepted there while indexing.
    outlier_px : float
        Smallest residual, in px, at which an indexed dot is rejected as a mis-indexed blob
        against a smooth (4th-order) fit of dot position over (row, col). That fit follows
        a 4-16 px distorted, tilted grid to 0.01-0.05 px, so a stray blob near a missing
        dot's place is caught unless it lies within about this distance of it.
    outlier_sigmas : float
        Residuals above this many robust standard deviations are rejected too (whichever
        of ``outlier_px`` and this is larger is the limit).
    anchor_centre : bool
        Re-express the optimal grid so that the correction and its gradient vanish at the
        normalisation centre (the image centre when the image size is known). Lens
        distortion vanishes to first order at the lens centre, so the corrected image
        keeps the scale, pixel aspect and orientation the lens has there, instead of the
        least-squares compromise of eq. 2.1 over the distorted field, which radial
        distortion biases (by up to 0.2 px at the field edge for 10 px corner distortion).
    perspective : {"lens_centre", "least_squares"}
        How the ``homography`` model settles the grid's perspective, which one planar
        view cannot separate from the quadratic part of the lens correction:
        ``"lens_centre"`` asks the correction to have no 2nd-order terms at the centre
        (as radial distortion has none); ``"least_squares"`` keeps the least-squares
        homography of the distorted dots.
    warn_residual_px : float
        Fit residual (RMS, px) above which a warning says the dots or their detection are
        suspect (rendered rig grids fit to 0.01-0.02 px).
    warn_cv_ratio : float
        Leave-one-row-out residual over fit residual above which a warning says the
        polynomial may be over-fitting.
    """

    section: ClassVar[str] = "grid"

    rows: int = param(15, ge=5)
    cols: int = param(20, ge=5)
    model: OptimalModel = param("homography")
    pixel_aspect: float | None = param(None, gt=0)
    cell_aspect: float = param(1.0, gt=0)
    min_indexed_fraction: float = param(0.9, gt=0, le=1)
    match_tol: float = param(0.3, gt=0, lt=0.5)
    outlier_px: float = param(0.25, unit="px", gt=0)
    outlier_sigmas: float = param(4.0, gt=0)
    anchor_centre: bool = param(True)
    perspective: Literal["lens_centre", "least_squares"] = param("lens_centre")
    warn_residual_px: float = param(0.1, unit="px", gt=0)
    warn_cv_ratio: float = param(2.0, gt=0)
