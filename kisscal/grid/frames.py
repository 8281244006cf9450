"""From recorded grid frames to dot centroids (Küçük 2005, section 2.2)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from kisscal.detect import DetectionParams, detect_blobs
from kisscal.detect.configure import configure_detection
from kisscal.detect.pipeline import check_image
from kisscal.errors import InputError
from kisscal.grid.fit import GridFit, linearise_dots
from kisscal.grid.params import GridParams


def average_frames(frames: Sequence[NDArray]) -> NDArray[np.float64]:
    """Mean of the grid frames, as float (the thesis linearises "the average of the images").

    Averaging n frames divides the pixel noise by sqrt(n) before any centroid is taken.

    Raises
    ------
    KisscalError
        No frames, or frames that are not 2-D images of one common shape.
    """
    if len(frames) == 0:
        raise InputError("no grid frames to average")
    first = np.asarray(frames[0])
    if first.ndim != 2:
        raise InputError(f"grid frames must be 2-D grey images, got shape {first.shape}")
    acc = np.zeros(first.shape, dtype=float)
    for k, frame in enumerate(frames):
        f = np.asarray(frame)
        if f.shape != first.shape:
            raise InputError(f"grid frame {k} has shape {f.shape}, the first one {first.shape}")
        acc += f
    return acc / len(frames)


def dots_from_frames(
    frames: Sequence[NDArray], detection: DetectionParams | None = None
) -> NDArray[np.float64]:
    """Average the grid frames and detect the dots with :mod:`kisscal.detect`.

    Parameters
    ----------
    frames : sequence of ndarray, shape (h, w)
        Grey frames of the grid from one camera (uint8 or float).
    detection : DetectionParams, optional
        Detection settings; derived from the frames themselves when not given
        (:func:`kisscal.detect.configure.configure_detection`, grid kind).

    Returns
    -------
    ndarray, shape (N, 2)
        Centroids ``(u, v)`` in px of the blobs detection judged valid.

    Notes
    -----
    Grid dots never touch, so the overlap and long/wide splits of Shafiq et al. 2001,
    sections 2.3.2-2.3.3 (meant for markers in motion) are switched off here: a large,
    slightly blurred dot would otherwise be cut in two halves 2-3 px apart. Frames are
    averaged on the grey scale detection uses for a single frame, so that a threshold
    means the same for 16-bit grid frames as for 16-bit trial frames.
    """
    image = average_frames([check_image(np.asarray(f)) for f in frames])
    if detection is None:
        detection = configure_detection(list(frames), kind="grid").params
    params = replace(detection, split_overlaps=False, split_long_wide=False)
    blobs = detect_blobs(image, params)
    ok = np.asarray(blobs.valid, dtype=bool)
    return np.column_stack([blobs.x_px[ok], blobs.y_px[ok]]).astype(float)


def linearise_frames(
    frames: Sequence[NDArray],
    params: GridParams | None = None,
    detection: DetectionParams | None = None,
) -> GridFit:
    """The whole grid stage for one camera: frames -> averaged image -> dots -> linearisation.

    Parameters
    ----------
    frames : sequence of ndarray, shape (h, w)
        Grey frames of the grid (one camera); their shape gives the image size used for
        the normalisation.
    params : GridParams, optional
        Grid size, optimal-grid model, tolerances.
    detection : DetectionParams, optional
        Detection settings (derived from the frames when not given).

    Returns
    -------
    GridFit
        ``fit.linearisation`` is what ``out/linearisation/<camera>.json`` stores.
    """
    dots = dots_from_frames(frames, detection)
    h, w = np.asarray(frames[0]).shape
    return linearise_dots(dots, params, size_px=(w, h))
