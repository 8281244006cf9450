"""Blob detection of one image (Shafiq et al. 2001, section 2)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from functools import partial
from typing import NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

import kisscal.detect.blobs as fl
from kisscal.detect.advanced import (
    Grouping,
    merge_submarkers,
    size_flags,
    splittable,
)
from kisscal.detect.appendage import detach_appendages, round_outline
from kisscal.detect.background import background_level, local_background
from kisscal.detect.blobs import Blobs
from kisscal.detect.centroid import Background, SpotMoments, window_moments
from kisscal.detect.cores import detach_cores
from kisscal.detect.detach import detach_from_large
from kisscal.detect.groups import GroupTable, measure_groups
from kisscal.detect.noise import noise_groups
from kisscal.detect.params import DetectionParams
from kisscal.detect.peaks import detect_peaks
from kisscal.detect.polarity import orient
from kisscal.detect.scan import group_runs
from kisscal.detect.splits import Spots, split_markers
from kisscal.detect.stack import Frames, unstack
from kisscal.errors import InputError

DEFAULT_PARAMS = DetectionParams()
#: A frame with more of its pixels white than this holds no spots to find: markers are a
#: small bright population on a darker surround (overexposed, or the threshold too low).
MAX_WHITE_FRACTION = 0.9
#: Least pixels of a group examined for thin appendages: a thick body (a disc of
#: :data:`~kisscal.detect.appendage.THICK_PX` radius) and something attached.
APPENDAGE_MIN_PIXELS = 40
#: Groups examined for appendages are at most this many times a marker's largest width
#: and height (or :data:`APPENDAGE_MAX_PX` without limits): a dot with a streak, not a
#: region.
APPENDAGE_EXTENT = 2
APPENDAGE_MAX_PX = 32
#: Most pixels of the frames :func:`detect_frames` stacks into one image (memory bound).
STACK_PX = 1 << 22
#: Least blank rows between stacked frames (more when the grouping reaches further).
STACK_GAP_ROWS = 8
#: Largest grey level a float image may hold (a 16-bit image's range).
MAX_FLOAT_GREY = 65535.0


def check_image(image: object) -> NDArray:
    """Return ``image`` as a 2-D array or raise :class:`KisscalError` saying what is wrong.

    Accepted: 2-D boolean (already thresholded), unsigned-integer or float grey images.
    Integer images wider than 8 bits are returned as float32 on the 8-bit grey scale.
    """
    if not isinstance(image, np.ndarray):
        raise InputError(f"detect: expected a 2-D numpy image, got {type(image).__name__}")
    if image.ndim == 3:
        raise InputError(
            f"detect: expected a single-channel image, got {image.shape[2]} channels "
            f"(shape {image.shape}); convert to grey first"
        )
    if image.ndim != 2:
        raise InputError(f"detect: expected a 2-D image, got shape {image.shape}")
    if image.size == 0:
        raise InputError(f"detect: empty image (shape {image.shape})")
    # dtype kinds: bool, unsigned integer, float (np.issubdtype costs more, per call)
    kind = image.dtype.kind
    if kind not in "buf":
        raise InputError(
            f"detect: unsupported image dtype {image.dtype}; use bool, uint8, uint16 or float"
        )
    if kind == "f":
        top = float(np.max(np.abs(image)))
        if not np.isfinite(top) or top > MAX_FLOAT_GREY:
            raise InputError(
                f"detect: float grey levels must be finite and within +-{MAX_FLOAT_GREY:g} "
                f"(8- or 16-bit scale), got {top:g}"
            )
    if kind == "u" and image.dtype.itemsize > 1:
        # 16-bit cameras: bring grey levels to the 8-bit scale so that ``threshold`` and the
        # other grey-level parameters mean the same for 8- and 16-bit frames of one scene.
        return image.astype(np.float32) * np.float32(255.0 / np.iinfo(image.dtype).max)
    return image


def threshold_image(image: NDArray, params: DetectionParams) -> tuple[NDArray, Background]:
    """The white pixels of a checked image and the background its centroids subtract.

    Global background (``background_tile_px`` 0): white is ``image >= threshold`` and the
    background one level, given or the median of a sparse sample. Local background: white
    stands ``threshold`` (and ``noise_factor`` local noise deviations) above the
    tile-median background map and the slack of its interpolation, and the weighted
    centroids subtract the map (:mod:`kisscal.detect.background`). A boolean image is white
    as it is, with no background.
    """
    if image.dtype == np.bool_:
        return image, 0.0
    if params.background_tile_px > 0:
        local = local_background(image, params.background_tile_px)
        above = np.float32(params.threshold)
        if params.noise_factor > 0:
            above = np.maximum(above, np.float32(params.noise_factor) * local.noise)
        return image >= local.level + local.slack + above, local.level
    level = background_level(image) if params.background is None else params.background
    return white_above(image, params.threshold), level


def hopeless(image: NDArray, params: DetectionParams) -> str | None:
    """Why no blob can be found in ``image`` with ``params``, in one line, or None.

    A frame more than :data:`MAX_WHITE_FRACTION` white at the threshold is not a marker
    image (overexposed, or a threshold below its background): :func:`detect_blobs`
    returns no blob for it at the cost of the threshold alone.
    """
    white, _ = threshold_image(orient(check_image(image), params.polarity), params)
    share = np.count_nonzero(white) / white.size
    if share <= MAX_WHITE_FRACTION:
        return None
    return (
        f"{share:.0%} of the frame is above the threshold: no spots to find (overexposed, "
        "or the threshold is below the background)"
    )


def white_above(image: NDArray, threshold: float) -> NDArray[np.bool_]:
    """``image >= threshold``, compared on the image's own integer scale when it has one.

    An integer grey level is at least a fractional threshold exactly when it is at least
    the threshold rounded up, so an 8-bit image compares with an 8-bit level: numpy would
    otherwise convert every pixel to float64 first (eight times the cheap comparison).
    """
    if image.dtype.kind not in "iu" or not math.isfinite(threshold):
        return image >= threshold
    level = math.ceil(threshold)
    info = np.iinfo(image.dtype)
    if level > info.max:
        return np.zeros(image.shape, dtype=bool)
    return image >= image.dtype.type(max(level, info.min))


def detect_blobs(image: NDArray, params: DetectionParams = DEFAULT_PARAMS) -> Blobs:
    """Find the marker images of one field: grouping, noise removal, advanced analysis.

    Parameters
    ----------
    image : ndarray, shape (h, w)
        Grey IR image (uint8, uint16 or float) or an already thresholded boolean image.
    params : DetectionParams
        Thresholds and switches; :func:`kisscal.detect.configure.configure_detection`
        derives the camera-dependent ones from a camera's images.

    Returns
    -------
    Blobs
        One row per group, sorted by the top-left corner of its bounding rectangle.
        Centroids are intensity-weighted (rim included, background subtracted) for grey
        images when ``params.weighted_centroid``; otherwise the binary centroid of
        equation (2). An image without white pixels gives an empty table, and so does
        one almost all white (:func:`hopeless` says why).

    Notes
    -----
    Steps: dark spots on a bright background inverted (``params.polarity``); threshold
    against a global or local background; run-length scan and grouping by run mid-points
    (Shafiq et al. 2001, section 2.1, eq. 3); noise removal (2.2); sub-marker merge
    (2.3.1); markers touching an LED ring separated from it and touching markers split
    at distance-transform peaks (kisscal's additions, each switchable);
    ul/ur overlap split (2.3.2, eqs. 4-6, plus a moment test for small diagonal pairs);
    long/wide split (2.3.3, ratio from growth-corrected moments); size limits (2.3.4).
    Coordinates keep the non-square pixels.

    Examples
    --------
    >>> import numpy as np
    >>> image = np.full((60, 80), 5, np.uint8)
    >>> image[20:25, 30:35] = 240                      # one bright 5 x 5 spot
    >>> blobs = detect_blobs(image)
    >>> len(blobs), float(blobs.x_px[0]), float(blobs.y_px[0])
    (1, 32.0, 22.0)
    """
    if params.route == "peaks":  # particle frames (kisscal.detect.peaks)
        return detect_peaks(orient(check_image(image), params.polarity), params)
    frame = _prepared(image, params)
    if frame is None:
        return Blobs.empty()
    grouped = _grouped(frame[1], params, frame[1].shape, None)
    if grouped is None:
        return Blobs.empty()
    return _finished(frame, *grouped, params)[0]


def detect_frames(
    images: Iterable[NDArray], params: DetectionParams = DEFAULT_PARAMS
) -> list[Blobs]:
    """:func:`detect_blobs` of each image, every step done once for many frames.

    Parameters
    ----------
    images : iterable of ndarray
        Images as :func:`detect_blobs` takes them (consecutive frames of one camera),
        read once in order: each is thresholded when it comes, so a loader's generator
        has it thresholded while its pixels are still in the processor's cache (the
        small session's threshold, background and count 0.60 -> 0.38 s, loaded a stack
        ahead against one at a time).
    params : DetectionParams
        Shared by all images.

    Returns
    -------
    list of Blobs
        What :func:`detect_blobs` gives for each image, in order.

    Notes
    -----
    Consecutive frames of one size and kind are stacked into one tall image (grey
    levels, white pixels, background), :data:`STACK_GAP_ROWS` (or more) blank rows apart
    so that no grouping reach (Shafiq et al. 2001, eq. 3), sub-marker rectangle or
    detach canvas joins two frames, at most :data:`STACK_PX` pixels at a time, and
    every step runs once on the stack: on small frames with a dozen spots the numpy
    calls' own overhead, paid once per stack instead of once per frame, is most of their
    cost. After the grouping steps (the LED-ring detach reads each frame's own border)
    the groups go back to their frames' coordinates, told apart by label
    (:func:`~kisscal.detect.stack.unstack`): cores, splits and moments compute from the
    same numbers as for each frame alone, read the grey levels at their frame's rows,
    and take what they need of a frame as a whole (its background level, its spots'
    growth and typical marker) from their own frame. Every step numbers the groups it
    makes after the ones there were, in table order, so each frame's groups keep the
    order that the frame alone gives them.
    """
    if params.route == "peaks":  # whole-image operations: nothing to share
        return [detect_blobs(image, params) for image in images]
    prepared = [(i, _prepared(image, params)) for i, image in enumerate(images)]
    out = [Blobs.empty()] * len(prepared)
    for stack in _stacks([(i, f) for i, f in prepared if f is not None]):
        height = stack[0][1][1].shape[0]
        gap = max(STACK_GAP_ROWS, params.closeness_rows + 1, params.submarker_margin_px + 2)
        rows = _Rows(height + gap, len(stack)) if len(stack) > 1 else None
        frame = _stacked([f for _i, f in stack], rows)
        shape = stack[0][1][1].shape
        grouped = _grouped(frame[1], params, shape, None if rows is None else rows.stride)
        if grouped is None:
            continue
        if rows is None:
            out[stack[0][0]] = _finished(frame, *grouped, params)[0]
            continue
        local, frames = unstack(grouped[0], rows.stride, height, len(stack))
        blobs, which = _finished(frame, local, measure_groups(local.runs), params, frames)
        bounds = np.searchsorted(which, np.arange(len(stack) + 1))
        for k, (i, _frame) in enumerate(stack):
            out[i] = blobs.select(np.arange(bounds[k], bounds[k + 1]))
    return out


_Frame = tuple[NDArray, NDArray[np.bool_], Background]


def _prepared(image: NDArray, params: DetectionParams) -> _Frame | None:
    """The checked, oriented image, its white pixels and background; None when it holds
    nothing to find (no white pixel, or almost all white: see :func:`hopeless`)."""
    image = orient(check_image(image), params.polarity)
    white, background = threshold_image(image, params)
    count = np.count_nonzero(white)
    if count == 0 or count > MAX_WHITE_FRACTION * white.size:
        return None
    return image, white, background


def _stacks(frames: list[tuple[int, _Frame]]) -> Iterator[list[tuple[int, _Frame]]]:
    """Runs of consecutive ``(index, frame)`` of one size and kind (grey type, one
    background level or a map), at most :data:`STACK_PX` pixels together (or one
    larger frame)."""
    stack: list[tuple[int, _Frame]] = []

    def kind(frame: _Frame) -> tuple[object, ...]:
        return frame[1].shape, frame[0].dtype, np.ndim(frame[2])

    for item in frames:
        white = item[1][1]
        if stack and (
            kind(stack[0][1]) != kind(item[1]) or (len(stack) + 1) * white.size > STACK_PX
        ):
            yield stack
            stack = []
        stack.append(item)
    if stack:
        yield stack


class _Rows(NamedTuple):
    """Frames stacked every ``stride`` rows, ``count`` of them."""

    stride: int
    count: int


def _stacked(frames: list[_Frame], rows: _Rows | None) -> _Frame:
    """The frames stacked every ``rows.stride`` rows, blank between (one frame: itself):
    grey levels, white pixels, and the background maps or one level per frame."""
    if rows is None:
        return frames[0]
    maps = np.ndim(frames[0][2]) == 2
    # Each stack written once, frames and blank gaps (np.zeros then the frames wrote the
    # frames' rows twice: 0.33x the decode of the small session's images, now ~0.2x).
    image = _banded([f[0] for f in frames], rows)
    white = _banded([f[1] for f in frames], rows)
    if maps:
        background = _banded([f[2] for f in frames], rows)
    else:
        background = np.array([f[2] for f in frames], dtype=np.float64)
    return image, white, background


def _banded(bands: list[NDArray], rows: _Rows) -> NDArray:
    """Equal-shaped 2-D ``bands`` one under the other every ``rows.stride`` rows, the
    rows between them zero."""
    height, width = bands[0].shape
    gap = np.zeros((rows.stride - height, width), dtype=bands[0].dtype)
    pieces = [gap] * (2 * len(bands) - 1)
    pieces[::2] = bands
    return np.concatenate(pieces)


def _grouped(
    white: NDArray[np.bool_],
    params: DetectionParams,
    shape: tuple[int, ...],
    stride: int | None,
) -> tuple[Grouping, GroupTable] | None:
    """Grouping, noise removal (2.2), sub-marker merge (2.3.1), the LED-ring detach and
    the appendage cut of the white pixels of one frame of ``shape``, or of frames of it
    stacked every ``stride`` rows; None when no group is left."""
    runs = group_runs(white, params.closeness_x_px, params.closeness_rows)
    if len(runs) == 0:
        return None
    grouping, table = _first_groups(Grouping.start(runs), params, shape, stride)
    if len(table) == 0:
        return None
    if params.detach_appendages:
        thin = _cut_appendages(grouping, table, params)
        if thin is not grouping:
            grouping, table = thin, measure_groups(thin.runs)
    return grouping, table


def _finished(
    frame: _Frame,
    grouping: Grouping,
    table: GroupTable,
    params: DetectionParams,
    frames: Frames | None = None,
) -> tuple[Blobs, NDArray[np.int64]]:
    """The steps that read the image and its statistics (each frame's own, for
    ``frames`` stacked): the core detach, the split tests with their moments, the
    high-pass centroids; the result table (one frame's after another) and each row's
    frame."""
    image, white, background = frame
    if params.detach_cores and params.apply_size_limits and image.dtype != np.bool_:
        cored = detach_cores(grouping, table, image, background, params, frames)
        if cored is not grouping:
            grouping, table = cored, measure_groups(cored.runs)
    spots = Spots(image, white, background, params, frames)
    grouping, table, moments = split_markers(grouping, table, spots, params)
    if params.centroid_highpass_px and image.dtype != np.bool_ and len(table):
        moments = highpass_moments(image, white, grouping, table, params, frames)
    frame = np.zeros(len(table), np.int64) if frames is None else frames.of(grouping, table)
    weighted = image.dtype != np.bool_
    return _blob_table(grouping, table, moments, params, (weighted, frame))


def highpass_moments(
    image: NDArray,
    white: NDArray[np.bool_],
    grouping: Grouping,
    table: GroupTable,
    params: DetectionParams,
    frames: Frames | None = None,
) -> SpotMoments:
    """Window moments weighing each pixel by how far it stands above the mean of the
    ``centroid_highpass_px`` square around it (zero below): a band-pass centroid
    (Crocker & Grier 1996) that dim halos and ghosts wider than the spot hardly move.
    For ``frames`` stacked in ``image`` each frame's mean is its own (its border
    reflected)."""
    side = int(params.centroid_highpass_px)
    # 8-bit frames stay 8-bit: a tenth of the float cost, the mean within half a level
    grey = image if image.dtype == np.uint8 else image.astype(np.float32, copy=False)
    if frames is None:
        mean = cv2.blur(grey, (side, side), borderType=cv2.BORDER_REFLECT)
    else:
        mean = np.zeros_like(grey)
        for k in range(frames.count):  # a few frames per stack
            band = slice(k * frames.stride, k * frames.stride + frames.height)
            mean[band] = cv2.blur(grey[band], (side, side), borderType=cv2.BORDER_REFLECT)
    return window_moments(
        np.maximum(grey, mean),
        white,
        grouping,
        table,
        params.centroid_margin_x_px,
        params.centroid_margin_y_px,
        mean,
        params.pixel_aspect,
        splittable(table, params),
        frames,
    )


def _cut_appendages(grouping: Grouping, table: GroupTable, params: DetectionParams) -> Grouping:
    """Thin appendages off thick spots (:mod:`kisscal.detect.appendage`): groups large
    enough for a thick body, not one round disc, at most a cluster's size and twice a
    marker's extent."""
    candidates = (table.pixels >= APPENDAGE_MIN_PIXELS) & splittable(table, params)
    # a dot and its streak: within twice a marker's extent (bounds the crops' canvas)
    for limit, extent in ((params.max_width_px, table.width), (params.max_height_px, table.height)):
        candidates &= extent <= APPENDAGE_EXTENT * (limit or APPENDAGE_MAX_PX)
    if candidates.any():
        candidates &= ~round_outline(
            grouping.runs, table, APPENDAGE_MIN_PIXELS, params.pixel_aspect
        )
    return detach_appendages(
        grouping, table, candidates, max(params.min_pixels, 2), params.pixel_aspect
    )


def _first_groups(
    grouping: Grouping, params: DetectionParams, shape: tuple[int, ...], stride: int | None
) -> tuple[Grouping, GroupTable]:
    """Noise removal (2.2), sub-marker merge (2.3.1) and the LED-ring detach.

    Each test returns the grouping itself when it changed nothing: no re-measuring then,
    nor after the noise removal, which leaves the other groups as they were.
    """
    table = measure_groups(grouping.runs)
    noise = noise_groups(table, params)
    if noise.any():
        grouping = grouping.keep_groups(table.label[noise])
        table = table.take(~noise)
    steps = []
    if params.merge_submarkers:
        steps.append(merge_submarkers)
    if params.detach_from_large and params.apply_size_limits:
        steps.append(partial(detach_from_large, shape=shape, stride=stride))
    for step in steps:
        if len(table) == 0:
            break
        changed = step(grouping, table, params)
        if changed is not grouping:
            grouping = changed
            table = measure_groups(grouping.runs)
    return grouping, table


def _blob_table(
    grouping: Grouping,
    table: GroupTable,
    moments: SpotMoments,
    params: DetectionParams,
    how: tuple[bool, NDArray[np.int64]],
) -> tuple[Blobs, NDArray[np.int64]]:
    """The result table: flags (size limits last), centroids (``how``: weighted ones or
    not, and each group's frame), sorted by frame and rectangle corner; each row's
    frame."""
    weighted, frame = how
    flags = grouping.flags[table.label]
    if params.apply_size_limits:
        flags = flags | size_flags(table, params)
    xb, yb = table.x_binary, table.y_binary
    x, y = (moments.x, moments.y) if weighted and params.weighted_centroid else (xb, yb)
    order = np.lexsort((table.x1, table.y1, frame))
    blobs = Blobs(
        x_px=x[order],
        y_px=y[order],
        x_binary_px=xb[order],
        y_binary_px=yb[order],
        pixels=table.pixels[order],
        w_px=table.width[order],
        h_px=table.height[order],
        valid=(flags[order] & fl.INVALID_FLAGS) == 0,
        flags=flags[order],
    )
    return blobs, frame[order]
