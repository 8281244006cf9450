"""From 3D points per field to labelled trajectories, and the thesis' PNC x MNC sweep."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.markersets.model import MarkerSet
from kisscal.tracking.blending import blend_tracks, clean_up
from kisscal.tracking.bodyfill import GapFill
from kisscal.tracking.gaps import fill_gaps_named
from kisscal.tracking.labelling import Labelling, label_tracks, label_with_set
from kisscal.tracking.labelling.anatomy import Anatomy
from kisscal.tracking.labelling.broken import drop_broken_samples
from kisscal.tracking.labelling.pieces import join_gap_pieces
from kisscal.tracking.labelling.sides import judge_sides
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs
from kisscal.tracking.smooth import smooth_tracks
from kisscal.tracking.stats import SegmentStats, segment_statistics
from kisscal.tracking.tracker import track_points
from kisscal.tracking.tracks import PREDICTED, Tracks

THESIS_PNC = (0.005, 0.05, 0.5)
THESIS_MNC = (0.1, 0.05, 0.025)


@dataclass(frozen=True)
class Trajectories:
    """Final trajectories of one trial.

    Attributes
    ----------
    tracks : Tracks
        One track per trajectory, numbered 0..n-1, samples measured / predicted / filled.
    labels : tuple of str
        Name of each track (marker name, or M1, M2, ...): the labelling's, then the names
        no piece took that were placed on one camera's rays
        (:func:`~kisscal.tracking.fill_absent.absent_tracks`).
    labelling : Labelling
        How labelling went: whether the marker set fits, unlabelled tracks, missing names
        (of which those placed are left out).
    n_predicted : (n,) int array
        Missing-point predictions (coasted fields) per track before gap filling
        (thesis table 5.13).
    n_pieces : int
        Track pieces formed by the tracker, before blending and clean-up.
    n_pieces_blended : int
        Tracks after blending and clean-up, before labelling joined pieces.
    fills : tuple of GapFill
        How each gap was filled (track, fields, method, expected error).
    """

    tracks: Tracks
    labels: tuple[str, ...]
    labelling: Labelling
    n_predicted: NDArray[np.int64]
    n_pieces: int
    n_pieces_blended: int
    fills: tuple[GapFill, ...] = ()


def build_trajectories(
    field: ArrayLike,
    xyz_mm: ArrayLike,
    params: TrackingParams | None = None,
    names: list[str] | tuple[str, ...] | None = None,
    template_mm: ArrayLike | None = None,
    segments: list[tuple[str, str]] | tuple | None = None,
    marker_set: MarkerSet | None = None,
    rate_hz: float | None = None,
    template_upright: bool = False,
    spare: SpareBlobs | None = None,
) -> Trajectories:
    """Track, blend, clean up, label, fill gaps and (optionally) smooth.

    Parameters
    ----------
    field : (N,) int array
        Field index of each 3D point.
    xyz_mm : (N, 3) float array
        The points (mm), e.g. ``points3d.csv`` of one trial.
    params : TrackingParams, optional
    names, template_mm, segments : optional
        The ``[markers]`` set of the session (names, standing-pose template, rigid pairs).
    marker_set : MarkerSet, optional
        A shipped set (restricted to the session's names, with the session's segments):
        names and segments come from it, ``template_mm`` may be left out
        (:func:`~kisscal.tracking.label_with_set`), and its anatomy judges the labels.
    rate_hz : float, optional
        Field rate; with it, labels are judged by the anatomy (left/right settled by the
        walking direction, a confidence per name): of ``marker_set``, or of the names'
        ``L``/``R`` convention.
    template_upright : bool
        ``template_mm`` is in the lab frame, Z up (a static trial's positions): with
        ``marker_set``, heights above the floor are checked too.
    spare : SpareBlobs, optional
        The trial's 2D blobs that no 3D point used, with the cameras
        (:func:`~kisscal.tracking.spare_blobs`): a filled sample that one camera still
        sees is moved onto that camera's ray (single-camera fill).
    """
    params = params or TrackingParams()
    raw = track_points(field, xyz_mm, params)
    blended = blend_tracks(raw, params)
    labelling = _label(
        blended, params, names, template_mm, segments, marker_set, rate_hz, template_upright
    )
    tracks = labelling.tracks
    n_predicted = tracks.n_status(PREDICTED)
    tracks, fills, placed = fill_gaps_named(
        tracks, params, spare, labelling.labels, labelling.unlabelled, labelling.missing
    )
    # names no piece took, placed on one camera's rays by their segment's lengths
    n_predicted = np.r_[n_predicted, np.zeros(len(placed), dtype=np.int64)]
    missing = tuple(n for n in labelling.missing if n not in placed)
    labelling = dataclasses.replace(labelling, missing=missing)
    if params.smoothing:
        tracks = smooth_tracks(tracks)
    return Trajectories(
        tracks=tracks,
        labels=labelling.labels + placed,
        labelling=labelling,
        n_predicted=n_predicted,
        n_pieces=raw.n_tracks,
        n_pieces_blended=clean_up(blended, params).n_tracks,
        fills=fills,
    )


def _label(
    blended: Tracks,
    params: TrackingParams,
    names: list[str] | tuple[str, ...] | None,
    template_mm: ArrayLike | None,
    segments: list[tuple[str, str]] | tuple | None,
    marker_set: MarkerSet | None,
    rate_hz: float | None,
    template_upright: bool = False,
) -> Labelling:
    """Label with the set, or with names and template; judged by the anatomy when the
    rate is known; measured samples that break their segment's lengths dropped; unnamed
    pieces that fill a named trajectory's gap joined to it."""
    template = None if template_mm is None else np.asarray(template_mm, dtype=float)
    if marker_set is not None and rate_hz:
        labelling = label_with_set(blended, marker_set, params, rate_hz, template, template_upright)
        return join_gap_pieces(drop_broken_samples(labelling, params), params)
    labelling = label_tracks(blended, names, params, template, segments)
    if rate_hz and names and template is not None:
        anatomy = Anatomy.of_names(tuple(names))
        if anatomy.pairs:
            labelling = judge_sides(labelling, anatomy, template, rate_hz, params)
    return join_gap_pieces(drop_broken_samples(labelling, params), params)


@dataclass(frozen=True)
class SweepRow:
    """One PNC/MNC combination: its segment statistics and predictions per label."""

    pnc: float
    mnc: float
    segments: tuple[SegmentStats, ...]
    predictions: dict[str, int]


def sweep_noise(
    field: ArrayLike,
    xyz_mm: ArrayLike,
    segments: list[tuple[str, str]] | tuple,
    params: TrackingParams | None = None,
    names: list[str] | tuple[str, ...] | None = None,
    template_mm: ArrayLike | None = None,
    pnc_values: tuple[float, ...] = THESIS_PNC,
    mnc_values: tuple[float, ...] = THESIS_MNC,
) -> list[SweepRow]:
    """The thesis' experiment (Küçük 2005 tables 5.1-5.13): track the trial with every PNC x
    MNC combination and tabulate segment lengths (measured vs Kalman-corrected) and the
    number of missing-point predictions per track.

    Segments refer to labels; without a marker set the tracks are M1, M2, ... and segments
    must use those names.
    """
    params = params or TrackingParams()
    rows = []
    for pnc in pnc_values:
        for mnc in mnc_values:
            # ``segments`` here are the pairs to tabulate (the thesis' include joints that
            # bend), so they are not handed to labelling as rigid pairs.
            result = build_trajectories(
                field, xyz_mm, params.replace(pnc=pnc, mnc=mnc), names, template_mm
            )
            stats = segment_statistics(result.tracks, result.labels, segments)
            preds = {lab: int(n) for lab, n in zip(result.labels, result.n_predicted, strict=True)}
            rows.append(SweepRow(pnc, mnc, tuple(stats), preds))
    return rows
