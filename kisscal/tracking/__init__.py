"""Trajectory generation: predictors, Kalman filter, gating, blending, gap filling, labels.

Typical use::

    from kisscal.tracking import TrackingParams, build_trajectories
    result = build_trajectories(field, xyz_mm, TrackingParams(), names, template_mm)
"""

from kisscal.tracking.association import associate
from kisscal.tracking.blending import blend_tracks, clean_up
from kisscal.tracking.labelling import Labelling, label_tracks
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.pipeline import (
    THESIS_MNC,
    THESIS_PNC,
    SweepRow,
    Trajectories,
    build_trajectories,
    sweep_noise,
)
from kisscal.tracking.rayfill import SpareBlobs, spare_blobs
from kisscal.tracking.smooth import smooth_tracks
from kisscal.tracking.stats import SegmentStats, segment_statistics
from kisscal.tracking.tracker import track_points
from kisscal.tracking.tracks import (
    FILLED,
    FILLED_PATTERN,
    FILLED_RIGID,
    MEASURED,
    PREDICTED,
    STATUS_NAMES,
    Tracks,
    is_filled,
)

__all__ = [
    "FILLED",
    "FILLED_PATTERN",
    "FILLED_RIGID",
    "MEASURED",
    "PREDICTED",
    "STATUS_NAMES",
    "THESIS_MNC",
    "THESIS_PNC",
    "Labelling",
    "SegmentStats",
    "SpareBlobs",
    "SweepRow",
    "TrackingParams",
    "Tracks",
    "Trajectories",
    "associate",
    "blend_tracks",
    "build_trajectories",
    "clean_up",
    "is_filled",
    "label_tracks",
    "segment_statistics",
    "smooth_tracks",
    "spare_blobs",
    "sweep_noise",
    "track_points",
]
