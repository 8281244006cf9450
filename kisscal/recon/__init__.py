"""3D reconstruction: stationary-ghost filter, epipolar matching, triangulation, grouping.

Typical use on a whole trial (long-format 2D table of linearised blobs)::

    from kisscal.recon import ReconParams, reconstruct_trial
    points = reconstruct_trial(field, camera, uv, dlts, ReconParams())
"""

from kisscal.recon.epipolar import (
    all_fundamentals,
    candidate_pairs,
    distance_matrix_px,
    epipolar_lines,
    fundamental_from_dlt,
    pair_distances_px,
)
from kisscal.recon.match import match_central, match_field, match_trial, match_triple
from kisscal.recon.pairs import continuity_mm, match_two_camera
from kisscal.recon.params import ReconParams
from kisscal.recon.reconstruct import (
    Points3D,
    coverage_warnings,
    points_from_markers,
    reconstruct_trial,
)
from kisscal.recon.stationary import at_epipoles, false_detections, stationary_mask

__all__ = [
    "Points3D",
    "ReconParams",
    "all_fundamentals",
    "at_epipoles",
    "candidate_pairs",
    "continuity_mm",
    "coverage_warnings",
    "distance_matrix_px",
    "epipolar_lines",
    "false_detections",
    "fundamental_from_dlt",
    "match_central",
    "match_field",
    "match_trial",
    "match_triple",
    "match_two_camera",
    "pair_distances_px",
    "points_from_markers",
    "reconstruct_trial",
    "stationary_mask",
]
