"""Which way round the objects are: bright spots on a dark surround, or dark on bright.

kisscal's detection finds bright spots (IR markers, lit particles, the white dots of a
back-lit target). Many calibration targets are printed the other way round: black dots on
a white plate, photographed in ordinary light. Such an image is recognised from two
pieces of evidence, and then inverted (grey level ``top - g``) before the rest of the
detection, which then sees bright dots on a dark plate:

- the background is the bright majority: the image's median sits far nearer its bright
  end than its dark end (the dark tail, median less the 0.1 th percentile, is at least
  :data:`DARK_TAIL_RATIO` times the bright tail, 99.9 th percentile less the median);
- the dark pixels form compact spots: at least :data:`MIN_SPOTS` dark components (half
  the dark tail below the median) no larger than :data:`MAX_SPOT_SHARE` of the frame,
  and more of them than bright ones as far above it (a dark object or frame border on a
  bright wall is not a target).

Everything else is read as bright spots (the detection's own convention), so a
bright-marker frame never turns on weak evidence. Statistics come from a sparse sample
(about :data:`SAMPLE_PIXELS` pixels), cheap beside the detection itself.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

#: Pixels of the sparse sample the decision reads.
SAMPLE_PIXELS = 60_000
#: The dark tail must be this many times the bright tail for a bright background.
DARK_TAIL_RATIO = 2.0
#: Least contrast (8-bit grey levels) between the background and the dark spots.
MIN_CONTRAST = 16.0
#: A dark spot covers at most this fraction of the frame.
MAX_SPOT_SHARE = 0.005
#: Least number of compact dark spots for a dot target.
MIN_SPOTS = 4


def dark_spots(image: NDArray) -> tuple[bool, str]:
    """Whether ``image`` shows dark spots on a bright background, and why.

    Parameters
    ----------
    image : ndarray, shape (h, w)
        A checked image (:func:`kisscal.detect.pipeline.check_image`): boolean, unsigned
        integer or float grey.

    Returns
    -------
    dark : bool
        True for dark spots on a bright background (the image is to be inverted).
    why : str
        The evidence, in one phrase.
    """
    if image.dtype == np.bool_:
        share = np.count_nonzero(image) / image.size
        return share > 0.5, f"{share:.0%} of the thresholded pixels are set"
    step = max(1, int(math.sqrt(image.size / SAMPLE_PIXELS)))
    sample = np.asarray(image[::step, ::step], dtype=np.float32)
    lo, med, hi = (float(v) for v in np.percentile(sample, [0.1, 50, 99.9]))
    dark, bright = med - lo, hi - med
    tails = f"dark tail {dark:.0f}, bright tail {bright:.0f} grey levels from the median {med:.0f}"
    if dark < DARK_TAIL_RATIO * bright or dark < MIN_CONTRAST:
        return False, f"bright spots on a darker background ({tails})"
    # spots as deep as half the dark tail, either way (the bright tail being at most half
    # of it, bright ones are glints at most, never the gradient or the noise of the plate)
    n_dark = _compact_spots(sample < med - 0.5 * dark)
    n_bright = _compact_spots(sample > med + 0.5 * dark)
    if n_dark < MIN_SPOTS or n_dark <= n_bright:
        return False, (
            f"a bright background but {n_dark} compact dark spots against {n_bright} bright "
            f"ones ({tails}): read as bright spots"
        )
    return True, f"{n_dark} compact dark spots on a bright background ({tails})"


def _compact_spots(mask: NDArray[np.bool_]) -> int:
    """Connected components of ``mask`` no larger than :data:`MAX_SPOT_SHARE` of it."""
    labels, n = ndimage.label(mask)
    if n == 0:
        return 0
    sizes = np.bincount(labels.ravel(), minlength=n + 1)[1:]
    return int(np.count_nonzero(sizes <= MAX_SPOT_SHARE * mask.size))


def invert(image: NDArray) -> NDArray:
    """The negative of a checked image on its own grey scale (dark spots turn bright).

    Unsigned integers: ``max - g`` of their type; float grey levels (8-bit scale, or 16-bit
    when above 255): ``255 - g`` or ``65535 - g``; boolean: ``~image``.
    """
    if image.dtype == np.bool_:
        return ~image
    if image.dtype.kind == "u":
        return np.iinfo(image.dtype).max - image
    top = 255.0 if float(np.max(image)) <= 255.0 else 65535.0
    return (image.dtype.type(top) - image).astype(image.dtype, copy=False)


def orient(image: NDArray, polarity: str) -> NDArray:
    """``image`` with its objects bright: inverted for "dark", and for "auto" when
    :func:`dark_spots` says so; as it is for "bright"."""
    if polarity == "bright":
        return image
    if polarity == "dark" or dark_spots(image)[0]:
        return invert(image)
    return image


def frames_polarity(frames: list[NDArray], polarity: str) -> tuple[str, str, list[NDArray]]:
    """A camera's polarity from a sample of its frames, why, and the frames oriented.

    "auto" becomes "dark" when most frames show dark spots on a bright background
    (:func:`dark_spots`), else "bright"; a polarity given stays as given.
    """
    if polarity == "auto":
        votes = [dark_spots(f) for f in frames]
        dark = sum(v for v, _ in votes)
        polarity = "dark" if 2 * dark > len(frames) else "bright"
        why = f"{dark} of {len(frames)} frames show dark spots; first: {votes[0][1]}"
    else:
        why = "from [detection]"
    if polarity == "dark":
        frames = [invert(f) for f in frames]
    return polarity, why, frames
