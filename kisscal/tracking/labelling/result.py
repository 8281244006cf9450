"""Phase 6: the labelling's result, pieces sharing a name joined into one trajectory."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from kisscal.tracking.labelling.state import LabelState
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import MEASURED, Tracks, make_tracks, numbering

#: Names that make a body whatever the size of the set: a trial holding this many of a
#: large set's names (a full-body set on a lower-body file) fits it.
MIN_BODY_NAMES = 8


@dataclass(frozen=True)
class Labelling:
    """Result of :func:`~kisscal.tracking.label_tracks`.

    Attributes
    ----------
    tracks : Tracks
        Tracks after joining pieces with the same label, numbered 0..n-1.
    labels : tuple of str
        Label per track of ``tracks``.
    fits_marker_set : bool
        Whether the trial's tracks fit the marker set (else all labels are M1, M2, ...).
    unlabelled : tuple of int
        Tracks (of ``tracks``) that fit no name of the marker set.
    missing : tuple of str
        Names of the marker set that no track took.
    fit_rms_mm : float
        Median over the sampled fields of the rigid fit RMS distance to the template.
    confidence : dict of str to float
        Per name, the fraction of fields in which its trajectory agrees with the anatomy
        (left of its right partner across the walking direction, above the markers far
        below it); names without a check are left out. Empty when not judged.
    flagged : tuple of str
        Names whose label is uncertain (confidence below ``min_side_confidence``, or left
        and right that nothing tells apart): not to be taken as certain.
    exchanged : tuple of (str, str)
        Left/right pairs whose labels were exchanged because the anatomy said so.
    mirror_fit_ratio : float
        Rigid-fit RMS of the labelling's mirror image (left and right names exchanged)
        over that of the labelling itself, both against the template: above 1, the
        labelling fits better than its mirror. NaN when not measured.
    height_mm : float
        The subject's stature estimated from the trial (labelling from a shipped set's
        generic template), else NaN.
    sides_from : str
        What settled left and right: ``"anatomy"`` (the walking direction or the pelvis
        and feet), ``"fit"`` (the template fit alone), or ``""`` when not judged.
    """

    tracks: Tracks
    labels: tuple[str, ...]
    fits_marker_set: bool
    unlabelled: tuple[int, ...]
    missing: tuple[str, ...]
    fit_rms_mm: float
    confidence: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    flagged: tuple[str, ...] = ()
    exchanged: tuple[tuple[str, str], ...] = ()
    mirror_fit_ratio: float = float("nan")
    height_mm: float = float("nan")
    sides_from: str = ""

    @property
    def certain(self) -> bool:
        """True when no label is flagged."""
        return not self.flagged


def generic(tracks: Tracks, params: TrackingParams, names: tuple, fit_rms: float) -> Labelling:
    """No marker set fits: clean up short tracks (unless ``keep_short_pieces``) and name
    the rest M1, M2, ..."""
    if not params.keep_short_pieces:
        tracks = tracks.select(tracks.n_status(MEASURED)[tracks.track] >= params.min_track_length)
    labels = tuple(f"M{i + 1}" for i in range(tracks.n_tracks))
    return Labelling(tracks, labels, False, (), names, fit_rms)


def join(state: LabelState) -> Labelling:
    """Phase 6: pieces sharing a name become one trajectory.

    Short pieces that fit no name are ghosts and are dropped (Shafiq et al. 2001's
    clean-up); long ones are kept, named ``M<k>`` and reported. When fewer than
    ``min_label_fraction`` of the names (nor :data:`MIN_BODY_NAMES`) were taken, the
    trial does not fit the set and every track is named M1, M2, ... (:func:`generic`).
    """
    tracks, params, names = state.tracks, state.params, state.names
    label_of, n_names = state.label_of, len(state.names)
    keep = (label_of >= 0) | (state.n_measured >= params.min_track_length)
    keep |= params.keep_short_pieces
    matched = np.unique(label_of[label_of >= 0])
    if matched.size < min(params.min_label_fraction * n_names, MIN_BODY_NAMES):
        return generic(tracks, params, names, state.fit_rms)
    # Unlabelled tracks keep their own group.
    group = np.where(label_of >= 0, label_of, n_names + np.arange(tracks.n_tracks))
    rows = keep[tracks.track]
    sample_group = group[tracks.track][rows]
    joined = make_tracks(
        tracks.field[rows],
        sample_group,
        tracks.xyz_mm[rows],
        tracks.corrected_mm[rows],
        tracks.status[rows],
        tracks.point[rows],
    )
    ids, rank, _ = numbering(tracks.field[rows], sample_group)
    new_group = np.empty(ids.size, dtype=np.int64)
    new_group[rank] = ids
    labels = []
    unlabelled = []
    for i, g in enumerate(new_group):
        if g < n_names:
            labels.append(names[g])
        else:
            unlabelled.append(i)
            labels.append(f"M{len(unlabelled)}")
    taken = set(matched.tolist())
    missing = tuple(n for j, n in enumerate(names) if j not in taken)
    doubtful = tuple(names[j] for j in sorted(state.doubtful) if j in taken)
    return Labelling(
        joined, tuple(labels), True, tuple(unlabelled), missing, state.fit_rms, flagged=doubtful
    )
