"""Threshold evidence on a noise-free (clipped or quantised) background.

The threshold of :mod:`kisscal.detect.configure` sits at a fraction of the contrast of
the faint end of the marker population, and at least five noise deviations above the
background. The noise is what keeps sensor specks out of that faint end: on a live
background they are below the floor. A background clipped to black (the camera's offset
below zero) or quantised flat has no measurable noise: over half of its neighbouring
pixels are equal, the noise reads 0 and the floor falls to a few grey levels, so faint
specks (dust, hot pixels, stray light on the target's plate) join the population, the
faint end becomes theirs and the threshold falls among them: tens of thousands of
blobs instead of the target's dots (issue 23, OpenPTV's example_2cam_90deg).

Without noise to tell specks from objects, the objects' own size must: the faint end
is then taken from the groups of the objects' size only, within two population gaps
(:data:`~kisscal.detect.population.SIZE_GAP` squared) below the largest objects
(:func:`~kisscal.detect.population.objects_top`), as the size limits already are. A
background with measurable noise keeps the faint end as it was.

Whatever the rule, a threshold that still leaves a crowd of groups per frame far beyond
any marker, dot or particle scene is reported (:func:`crowd_notes`) rather than left to
cost seconds per image silently.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import NDArray

from kisscal.detect.params import DetectionParams
from kisscal.detect.pipeline import threshold_image
from kisscal.detect.population import SIZE_GAP
from kisscal.detect.survey import GreyLevels, Groups

#: Groups (at least two pixels wide and high, as noise removal keeps) per frame beyond
#: which the threshold is in the specks: the densest particle frames seen (the OpenPTV
#: cavity) hold under 4 000, a noise-free background thresholded at 3 grey levels 73 000.
CROWD_MAX = 20_000
#: Frames of the sample counted for the crowd (thresholding and labelling, ~0.1 s each).
CROWD_FRAMES = 3


def noise_free(levels: GreyLevels) -> bool:
    """Whether the background's noise is not measurable (reads below half a grey level)."""
    return levels.noise < 0.5 * levels.unit


def faint_sample(
    groups: Groups, markers: NDArray[np.bool_], top: float | None, levels: GreyLevels
) -> Groups:
    """The groups whose peaks give the faint end of the markers' contrast.

    Parameters
    ----------
    groups : Groups
        First survey's groups.
    markers : ndarray of bool
        The marker population (:func:`~kisscal.detect.population.marker_population`).
    top : float or None
        Area (px) of the largest objects.
    levels : GreyLevels
        Background and noise of the frames.

    Returns
    -------
    Groups
        The markers; on a noise-free background only those of the objects' size (all
        the markers when none is).
    """
    if not noise_free(levels) or top is None:
        return groups.take(markers)
    sized = markers & (groups.pixels >= top / SIZE_GAP**2)
    return groups.take(sized if sized.any() else markers)


def crowd_notes(frames: Sequence[NDArray], params: DetectionParams) -> tuple[str, ...]:
    """A warning when ``params`` leave a crowd of groups per frame.

    Detection's cost grows with its groups: tens of thousands per image take seconds
    where OpenCV's labelling takes a tenth. Counted on a few of the frames with OpenCV's
    connected components (8-connected, as detection groups) before detection runs, so
    that a threshold among the specks is reported at once.

    Parameters
    ----------
    frames : sequence of ndarray
        Checked frames (as :func:`~kisscal.detect.pipeline.check_image` returns them).
    params : DetectionParams
        The settings chosen.

    Returns
    -------
    tuple of str
        Empty, or one note (also issued as a :class:`UserWarning`).
    """
    counts = []
    for image in frames[:CROWD_FRAMES]:
        white, _ = threshold_image(image, params)
        _, _, stats, _ = cv2.connectedComponentsWithStats(white.view(np.uint8), connectivity=8)
        counts.append(int(np.count_nonzero((stats[1:, 2] > 1) & (stats[1:, 3] > 1))))
    per_frame = int(np.median(counts)) if counts else 0
    if per_frame <= CROWD_MAX:
        return ()
    note = (
        f"threshold {params.threshold:.3g} leaves {per_frame} groups per frame: it is in the "
        "specks, not under the markers; detection will be slow and noisy: give "
        "a higher [detection] threshold"
    )
    warnings.warn(note, stacklevel=3)
    return (note,)
