"""Grid linearisation: lattice indexing, primary/optimal grid, 4th-order polynomial fit.

Küçük 2005, section 2.2 and 3.3.2; Shafiq et al. 2001, section 3.2. Typical use::

    fit = linearise_frames(frames, GridParams(), detection_params)  # one camera
    fit.linearisation            # 30 coefficients + normalisation + quality figures
    fit.warnings()               # missing dots, rejected blobs, over-fitting
    corrected = apply_linearisation(fit.linearisation, uv)

or, from dot centroids, ``linearise_dots(dots_uv, GridParams(), size_px=(752, 291))``.
"""

from kisscal.grid.fit import GridFit, fit_linearisation, linearise_dots, normalisation
from kisscal.grid.frames import average_frames, dots_from_frames, linearise_frames
from kisscal.grid.lattice import LatticeIndex, index_lattice, lattice_vectors
from kisscal.grid.optimal import OptimalGrid, PrimaryGrid, optimal_grid, primary_grid
from kisscal.grid.params import GridParams
from kisscal.grid.poly import (
    TERM_NAMES,
    Linearisation,
    LinearisationQuality,
    apply_linearisation,
    fit_polynomial,
    identity_linearisation,
    invert_linearisation,
    poly_terms,
)
from kisscal.grid.quality import (
    leave_rows_out_rms,
    line_distances,
    rms_px,
    straightness_noise_floor_px,
    straightness_rms,
)

__all__ = [
    "TERM_NAMES",
    "GridFit",
    "GridParams",
    "LatticeIndex",
    "Linearisation",
    "LinearisationQuality",
    "OptimalGrid",
    "PrimaryGrid",
    "apply_linearisation",
    "average_frames",
    "dots_from_frames",
    "fit_linearisation",
    "fit_polynomial",
    "identity_linearisation",
    "index_lattice",
    "invert_linearisation",
    "lattice_vectors",
    "leave_rows_out_rms",
    "line_distances",
    "linearise_dots",
    "linearise_frames",
    "normalisation",
    "optimal_grid",
    "poly_terms",
    "primary_grid",
    "rms_px",
    "straightness_noise_floor_px",
    "straightness_rms",
]
