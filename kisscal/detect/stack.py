"""Frames of one size stacked into one tall image, and the per-frame values read from it.

:func:`kisscal.detect.pipeline.detect_frames` stacks consecutive frames, blank rows
apart, so that each detection step runs once for many frames (on small frames with a
dozen spots the numpy calls' own overhead is most of their cost). After the grouping
steps the groups' runs go back to their own frame's coordinates (:func:`unstack`), all
frames' groups in one grouping told apart by label, so that every centroid, moment and
split centre is computed from the same numbers as for the frame alone; only the grey
levels, white pixels and background are read from the stack, each group at its own
frame's rows. What a step takes from a frame as a whole (its background level, a median
over its groups: :func:`~kisscal.detect.shape.frame_medians`) is taken per frame, each
group reading its own frame's value.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.detect.advanced import Grouping
from kisscal.detect.groups import GroupTable
from kisscal.detect.scan import Runs


@dataclass(frozen=True)
class Frames:
    """``count`` frames of ``height`` rows stacked every ``stride`` rows, and the frame
    of each group label there was when they were unstacked (its parts, made later, have
    it as ``parent``)."""

    stride: int
    height: int
    count: int
    label_frame: NDArray[np.int64]

    def of(self, grouping: Grouping, table: GroupTable) -> NDArray[np.int64]:
        """The frame of each group of ``table``."""
        return self.label_frame[grouping.parent[table.label]]


def unstack(grouping: Grouping, stride: int, height: int, count: int) -> tuple[Grouping, Frames]:
    """The groups of ``count`` frames stacked every ``stride`` rows, their runs and split
    centres in their own frame's coordinates, and the frames they belong to."""
    runs = grouping.runs
    frame = runs.y // stride
    label_frame = np.zeros(grouping.flags.size, dtype=np.int64)
    label_frame[runs.group] = frame
    label_frame[grouping.parent[runs.group]] = frame  # a group's parts share its frame
    top = label_frame[grouping.parent] * stride
    local = Grouping(
        Runs(runs.y - frame * stride, runs.x1, runs.x2, runs.group),
        grouping.flags.copy(),
        grouping.parent,
        grouping.centre_x,
        grouping.centre_y - top,
        grouping.radius,
    )
    return local, Frames(stride, height, count, label_frame)


def background_at(
    background: float | NDArray[np.floating],
    flat: NDArray[np.int64],
    frame: NDArray[np.int64] | None,
) -> float | NDArray[np.floating]:
    """The background at pixels ``flat`` (indices into the image) of frames ``frame``:
    one level, a map of the image's shape, or one level per frame (1-D, stacked)."""
    ndim = np.ndim(background)
    if ndim == 0:
        return background  # type: ignore[return-value]
    if ndim == 1:
        return np.asarray(background).take(0 if frame is None else frame)
    return np.asarray(background).ravel().take(flat)
