"""Whether single markers image as round spots: the condition of the shape-only split tests.

The overlap and long/wide tests of Shafiq et al. 2001 (sections 2.3.2 and 2.3.3) take a
group that is not round for two markers. Isolated spots, single objects for sure, show
whether that holds. Two ways it fails:

- many isolated spots have an odd height-to-width ratio (irregular particles, comet tails,
  halos, a target's dots seen tilted about a horizontal or vertical axis);
- most isolated spots are ellipses along one common axis, elongated as much as the overlap
  test cuts (a target's dots seen tilted about a diagonal): their ratio reads round, but the
  overlap test cuts each one in two. Touching markers and motion blur do not look like this:
  a pair is about twice a single marker and rare among isolated spots, and blur stretches
  only the markers that move fast, each along its own path, so most spots stay round.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

import kisscal.detect.blobs as fl
from kisscal.detect.aspect import MIN_SPOTS_FOR_ASPECT
from kisscal.detect.params import DetectionParams
from kisscal.detect.pipeline import detect_blobs
from kisscal.detect.shape import corrected_moments, height_ratio, principal_axes
from kisscal.detect.survey import Groups

#: Share of single spots the shape tests may cut and stay on: beyond, they cut more than free.
ODD_SHAPES_MAX = 0.15
#: Share of single spots that, elongated along one axis, make single markers ellipses: most
#: of them (a marker that moves or touches another is the exception among isolated spots).
ALIGNED_ELLIPSES_MIN = 0.5
#: Most frames on which the shape tests are tried on the isolated spots (the first ones).
SHAPE_TRIAL_FRAMES = 3
#: Flags of a part cut by the shape tests (overlap and long/wide).
SHAPE_CUTS = fl.SPLIT_UL | fl.SPLIT_UR | fl.SPLIT_WIDE | fl.SPLIT_LONG


def aligned_ellipses(
    var_x: NDArray[np.float64],
    var_y: NDArray[np.float64],
    cov_xy: NDArray[np.float64],
    params: DetectionParams,
) -> float:
    """Share of spots elongated along one common axis as much as the overlap test cuts.

    Parameters
    ----------
    var_x, var_y, cov_xy : ndarray
        Corrected second moments (:func:`~kisscal.detect.shape.corrected_moments`).
    params : DetectionParams
        ``pixel_aspect``, ``overlap_min_elongation`` and ``overlap_angle_deg`` (the
        tolerance about the common axis) are read.

    Returns
    -------
    float
        The share (0 without any elongated spot). The common axis is the mean of the
        elongated spots' axes as doubled angles (an axis has no sign; Mardia and Jupp 2000).
    """
    major, minor, ux, uy = principal_axes(var_x, var_y, cov_xy, params.pixel_aspect)
    elongated = np.sqrt(major / minor) >= params.overlap_min_elongation
    if not elongated.any():
        return 0.0
    doubled = (ux + 1j * uy) ** 2
    axis = doubled[elongated].mean()
    off = np.abs(np.angle(doubled * np.conj(axis))) / 2  # radians between the two axes
    along = off <= np.radians(params.overlap_angle_deg)
    return float(np.mean(elongated & along))


def shapes_off_reason(
    var_x: NDArray[np.float64],
    var_y: NDArray[np.float64],
    cov_xy: NDArray[np.float64],
    params: DetectionParams,
) -> str | None:
    """Why the shape tests must be off on these isolated spots, or None when they hold.

    Parameters
    ----------
    var_x, var_y, cov_xy : ndarray
        Raw second moments of the isolated spots (px^2), as the survey measures them; the
        pixel area and ``params.growth_px`` are removed here, as the tests remove them.
    params : DetectionParams
        The settings derived so far.
    """
    cvx, cvy, cxy = corrected_moments(var_x, var_y, cov_xy, params.growth_px)
    ratio = height_ratio(cvx, cvy, params.pixel_aspect)
    odd = float(np.mean((ratio < params.min_ratio) | (ratio > params.max_ratio)))
    n = var_x.size
    if odd > ODD_SHAPES_MAX:
        return (
            f"{odd:.0%} of {n} isolated spots are not round: shape alone does not tell two "
            "markers from one"
        )
    aligned = aligned_ellipses(cvx, cvy, cxy, params)
    if aligned > ALIGNED_ELLIPSES_MIN:
        return (
            f"{aligned:.0%} of {n} isolated spots are ellipses along one axis (a target seen "
            "obliquely): the overlap test would cut single markers"
        )
    return None


def cut_singles_reason(
    frames: Sequence[NDArray], singles: Groups, params: DetectionParams
) -> str | None:
    """Why the shape tests must be off: they cut too many isolated spots, or None.

    The survey's moments weigh a spot's whole blurred light; the tests read its white
    pixels at the threshold. A dot with a glint (a bead lit from one side) reads round by
    the first and wide, or as an overlapped pair, by the second. So the tests are run on
    the first frames, and an isolated spot (one object for sure) with a part they cut
    within its half-extent counts as cut.
    """
    # the first frames, enough for twice the spots an aspect needs (each costs a pass)
    seen = np.cumsum(np.bincount(singles.frame, minlength=len(frames)))
    last = min(int(np.searchsorted(seen, 2 * MIN_SPOTS_FOR_ASPECT)), SHAPE_TRIAL_FRAMES - 1)
    tried = singles.take(singles.frame <= last)
    cut = np.zeros(len(tried.frame), dtype=bool)
    for f in np.unique(tried.frame):
        blobs = detect_blobs(frames[f], params.replace(polarity="bright"))  # oriented
        parts = (blobs.flags & SHAPE_CUTS) != 0
        if not parts.any():
            continue
        here = tried.frame == f
        centres = np.column_stack([tried.x[here], tried.y[here]])
        reach = np.maximum(tried.width[here], tried.height[here]) / 2.0
        xy = np.column_stack([blobs.x_px[parts], blobs.y_px[parts]])
        near = cKDTree(xy).query_ball_point(centres, reach, return_length=True)
        cut[here] = np.asarray(near) > 0
    share = float(cut.mean()) if cut.size else 0.0
    if share <= ODD_SHAPES_MAX:
        return None
    return (
        f"the shape tests cut {share:.0%} of {cut.size} isolated spots (one object each; "
        "a glint or an irregular outline at the threshold): shape alone does not tell two "
        "markers from one"
    )
