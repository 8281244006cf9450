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

Both read the shapes of the survey's spots; what the tests then do to the frames is
checked too (:func:`single_cuts_reason`): a cut whose pieces together cover less than
:data:`SINGLE_SIZE` typical whole markers cut one marker. A target's
dots seen a little obliquely, round enough to pass the share above but the widest just
past the long/wide test's ratio, are cut so (OpenPTV's one-dot-example splitter: 7-12
of about 100 dots a view); a synthetic walk's tests cut at most 1 marker in 200 so.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

import kisscal.detect.blobs as fl
from kisscal.detect.blobs import Blobs
from kisscal.detect.params import DetectionParams
from kisscal.detect.pipeline import detect_blobs
from kisscal.detect.shape import corrected_moments, height_ratio, principal_axes

#: Share of single spots the shape tests may cut and stay on: beyond, they cut more than free.
ODD_SHAPES_MAX = 0.15
#: Share of single spots that, elongated along one axis, make single markers ellipses: most
#: of them (a marker that moves or touches another is the exception among isolated spots).
ALIGNED_ELLIPSES_MIN = 0.5
#: Share of the whole markers the shape tests may cut at one marker's size and stay on.
SINGLE_CUTS_MAX = 0.05
#: ... and the least number of such cuts that tells (a pair of small markers may be one).
SINGLE_CUTS_MIN = 3
#: Pieces smaller together than this many typical whole markers were one marker: two
#: equal round markers the long/wide test sees (height / width under 0.78, their centres
#: 0.4 diameters apart or more) cover 1.5 markers or more; one ellipse that wide, less.
SINGLE_SIZE = 1.5
#: Frames of the sample the cuts are counted on (spread over it).
CUT_FRAMES = 8
_SHAPE_CUTS = fl.SPLIT_WIDE | fl.SPLIT_LONG | fl.SPLIT_UL | fl.SPLIT_UR


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


def single_marker_cuts(blobs: Blobs) -> tuple[int, int]:
    """Shape-test cuts of one frame whose pieces together are one typical marker, and
    the frame's whole (uncut) valid markers.

    The pieces of one cut touch: valid pieces within a typical marker's diameter of each
    other are one cut; the typical marker is the median whole one.
    """
    valid = blobs.valid_only()
    cut = (valid.flags & _SHAPE_CUTS) != 0
    whole = int(np.count_nonzero(~cut))
    if not cut.any() or whole == 0:
        return 0, whole
    typical = float(np.median(valid.pixels[~cut]))
    xy = valid.xy_px[cut]
    pairs = cKDTree(xy).query_pairs(2.0 * np.sqrt(typical / np.pi), output_type="ndarray")
    n = len(xy)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, cut_of = connected_components(graph, directed=False)
    size = np.bincount(cut_of, weights=valid.pixels[cut].astype(float))
    return int(np.count_nonzero(size < SINGLE_SIZE * typical)), whole


def single_cuts_reason(frames: Sequence[NDArray], params: DetectionParams) -> str | None:
    """Why the shape tests must be off because they cut single markers, or None.

    Parameters
    ----------
    frames : sequence of ndarray
        The sample the settings were derived from (up to :data:`CUT_FRAMES`, spread over
        it, are detected).
    params : DetectionParams
        The derived settings; only the blob route with a shape test on is checked.
    """
    if params.route != "blobs" or not (params.split_overlaps or params.split_long_wide):
        return None
    step = max(1, len(frames) // CUT_FRAMES)
    counts = np.array([single_marker_cuts(detect_blobs(f, params)) for f in frames[::step]])
    singles, whole = counts.sum(axis=0)
    if singles < SINGLE_CUTS_MIN or singles <= SINGLE_CUTS_MAX * whole:
        return None
    return (
        f"the shape tests cut {singles} of {singles + whole} markers smaller than two "
        "overlapped ones: single markers (a target's dots seen obliquely), not pairs"
    )
