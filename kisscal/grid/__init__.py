"""Grid linearisation: lattice indexing, primary/optimal grid, 4th-order polynomial fit.

Küçük 2005, section 2.2 and 3.3.2; Shafiq et al. 2001, section 3.2. Typical use::

    fit = linearise_frames(frames, GridParams(), detection_params)  # one camera
    fit.linearisation            # 30 coefficients + normalisation + quality figures
    fit.warnings()               # missing dots, rejected blobs, over-fitting
    corrected = apply_linearisation(fit.linearisation, uv)

or, from dot centroids, ``linearise_dots(dots_uv, GridParams(), size_px=(752, 291))``.
"""

from kisscal.grid.fit import GridFit, linearise_dots
from kisscal.grid.frames import average_frames, dots_from_frames, linearise_frames
from kisscal.grid.lattice import index_lattice
from kisscal.grid.params import GridParams
from kisscal.grid.poly import (
    Linearisation,
    apply_linearisation,
    identity_linearisation,
    invert_linearisation,
    poly_terms,
)
from kisscal.grid.quality import line_distances, straightness_noise_floor_px, straightness_rms

__all__ = [
    "GridFit",
    "GridParams",
    "Linearisation",
    "apply_linearisation",
    "average_frames",
    "dots_from_frames",
    "identity_linearisation",
    "index_lattice",
    "invert_linearisation",
    "line_distances",
    "linearise_dots",
    "linearise_frames",
    "poly_terms",
    "straightness_noise_floor_px",
    "straightness_rms",
]
