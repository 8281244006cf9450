"""Labelling with a shipped marker set alone: the subject's own template, from the trial.

A shipped set's template is a typical adult of 1.75 m standing; the subject is taller or
shorter, places markers a little differently, and walks. So:

1. **stature**: the set's template is scaled (isometrically) to the statures 0.80-2.00 m
   (1.40-2.00 m for a part of the set: a lower body fits the whole body of a smaller
   subject about as well as its own) and matched to the average pose of a window of
   about one stride (:func:`estimate_height`); the best fit gives the subject's stature;
2. **first pass**: the phases run with the scaled template and without rigid
   segments (their lengths are the subject's, not the template's); a part of the set
   fitted at its bound takes the stature whose first pass holds the most segments
   rigid, all its names then flagged
   (:func:`~kisscal.tracking.labelling.partial.rigid_height`);
3. **the subject's template** (:func:`fit_template`): the scaled template, moved as
   little as possible so that every pair the first pass found rigid (and the set's
   segments) has its measured length; left/right are settled by the anatomy first;
4. **second pass**: from the first pass' names of the long pieces, the phases spread
   names again with the subject's template and the set's segments, and a piece rigid
   with a segment whose other name the trial never showed takes that name
   (:func:`~kisscal.tracking.labelling.unseen.name_by_segment`); the result is
   judged by the anatomy (:func:`~kisscal.tracking.labelling.sides.judge_sides`), and
   its doubted names given again where a free name fits better
   (:func:`~kisscal.tracking.labelling.regive.regive_doubted`); a part's names that the
   set's rigid segments do not vouch for are flagged
   (:func:`~kisscal.tracking.labelling.partial.unvouched`).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix, identity, vstack

from kisscal.markersets.model import MarkerSet
from kisscal.tracking.labelling.anatomy import Anatomy, settle_sides
from kisscal.tracking.labelling.core import crowded, held_whole
from kisscal.tracking.labelling.feet import settle_feet
from kisscal.tracking.labelling.footorder import out_of_order_feet
from kisscal.tracking.labelling.groups import name_groups
from kisscal.tracking.labelling.label import label_tracks
from kisscal.tracking.labelling.learned import name_from_trial
from kisscal.tracking.labelling.partial import first_pass, rigid_height, unvouched
from kisscal.tracking.labelling.regive import regive_doubted
from kisscal.tracking.labelling.result import Labelling, generic, join
from kisscal.tracking.labelling.sides import judge_sides
from kisscal.tracking.labelling.spread import rematch, spread
from kisscal.tracking.labelling.state import (
    MIN_SHARED_FIELDS,
    RIGID_SPREAD_MM,
    LabelState,
    segment_mask,
)
from kisscal.tracking.labelling.unseen import name_by_segment
from kisscal.tracking.labelling.upright import capped_assignment, fit_on_floor
from kisscal.tracking.labelling.vertical import turned, upright_rotation
from kisscal.tracking.labelling.window import first_pose, match_first_window
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import Tracks

#: Statures (mm) tried when the subject's is unknown: children to tall adults.
HEIGHTS_MM = np.arange(800.0, 2001.0, 50.0)
#: Statures (mm) tried when the trial holds only part of the set. A part's pose fits the
#: whole body of a smaller subject about as well as its own subject's (a lower body of
#: 1.45 m is matched by the legs and trunk of a 0.90 m template, issue 26): below
#: 1.40 m the fit cannot tell the two apart, so the range stays adult and a best fit at
#: its bound leaves every name doubtful.
PARTIAL_HEIGHTS_MM = HEIGHTS_MM[HEIGHTS_MM >= 1400.0]
#: How much a template position may move (mm) per mm of segment length it puts right.
PRIOR_WEIGHT = 0.05


def partial_height(tracks: Tracks, marker_set: MarkerSet, params: TrackingParams) -> float:
    """Stature (mm) whose scaled template the first window's average pose, stood on it,
    fits best (capped cost, :func:`~kisscal.tracking.labelling.upright.fit_on_floor`), when
    the trial holds only part of the set, or crowds it with other markers
    (:func:`~kisscal.tracking.labelling.core.crowded`; NaN otherwise, or without a
    pose).

    Distances of a part of the set and of foreign markers do not match a scaled template
    however tall; the pose stood on the floor does.
    """
    state = LabelState.begin(tracks, marker_set.names, marker_set.template_mm, None, params)
    if state is None:
        return float("nan")
    pos, pose = first_pose(state)
    seen = np.isfinite(pose[:, 0])
    if seen.sum() < 3:
        return float("nan")
    cap = params.label_tolerance_mm
    fits = []
    for height in PARTIAL_HEIGHTS_MM:
        template = marker_set.scaled(float(height)).template_mm
        cost, r, t = fit_on_floor(pose[seen], pos, template, cap)
        held = capped_assignment(pose[seen] @ r.T + t, template, cap)[0].size
        fits.append((cost, float(height), held))
    cost, height, held = min(fits)
    n = len(marker_set.names)
    if held_whole(held, n) and not crowded(int(seen.sum()), n):
        return float("nan")
    return height


def estimate_height(
    tracks: Tracks, marker_set: MarkerSet, params: TrackingParams
) -> tuple[float, bool]:
    """Stature (mm) whose scaled template fits the first window's average pose best
    (NaN when no stature gives a match), and whether the trial holds only part of the set
    (the stature then from :func:`partial_height`, among :data:`PARTIAL_HEIGHTS_MM`).

    Phase 1 (:func:`~kisscal.tracking.labelling.window.match_first_window`) runs with the
    template scaled to each of :data:`PARTIAL_HEIGHTS_MM` (adults); the lowest fit RMS
    wins, and only when it is the lowest adult stature are the smaller statures of
    :data:`HEIGHTS_MM` tried too (each stature costs a first-window match).
    """
    partial = partial_height(tracks, marker_set, params)
    if np.isfinite(partial):
        return partial, True
    rms, height = _window_fit(tracks, marker_set, params, PARTIAL_HEIGHTS_MM)
    if height == PARTIAL_HEIGHTS_MM[0]:
        small = HEIGHTS_MM[HEIGHTS_MM < height]
        small_rms, small_height = _window_fit(tracks, marker_set, params, small)
        if small_rms < rms:
            height = small_height
    return height, False


def _window_fit(
    tracks: Tracks, marker_set: MarkerSet, params: TrackingParams, heights: NDArray
) -> tuple[float, float]:
    """(fit RMS, stature) of the best first-window match among ``heights`` (inf, NaN
    when none matches)."""
    best_rms, best_height = np.inf, float("nan")
    for height in heights:
        scaled = marker_set.scaled(float(height))
        state = LabelState.begin(tracks, scaled.names, scaled.template_mm, None, params)
        if state is None:
            return np.inf, float("nan")
        state.upright = True
        if match_first_window(state) and state.fit_rms < best_rms:
            best_rms, best_height = state.fit_rms, float(height)
    return best_rms, best_height


def fit_template(
    name_pos: NDArray, template: NDArray, rigid: NDArray, min_shared: int = MIN_SHARED_FIELDS
) -> NDArray[np.float64]:
    """The template moved as little as possible for the subject's rigid pairs to have
    their measured length.

    Pairs: the ``rigid`` mask (the set's segments) and every two named trajectories whose
    distance varies by less than the rigid spread (5 mm SD) over at least ``min_shared``
    common fields. Least squares over the positions: the length misfits (mm) plus
    :data:`PRIOR_WEIGHT` times the displacement from ``template``.
    """
    pts = name_pos
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # pairs never seen together
        d = np.linalg.norm(pts[:, None] - pts[None, :], axis=3)
        count = np.isfinite(d).sum(axis=2)
        median = np.nanmedian(d, axis=2)
        sd = np.nanstd(d, axis=2)
    use = (rigid | (sd < RIGID_SPREAD_MM)) & (count >= min_shared)
    a, b = np.nonzero(np.triu(use, 1))
    if a.size == 0:
        return template.copy()
    length = median[a, b]
    n = template.shape[0]
    rows = np.repeat(np.arange(a.size), 6)
    cols = np.concatenate([3 * a[:, None] + np.arange(3), 3 * b[:, None] + np.arange(3)], axis=1)
    prior = PRIOR_WEIGHT * identity(3 * n, format="csr")

    def residuals(x: NDArray) -> NDArray:
        p = x.reshape(-1, 3)
        misfit = np.linalg.norm(p[a] - p[b], axis=1) - length
        return np.r_[misfit, PRIOR_WEIGHT * (x - template.ravel())]

    def jacobian(x: NDArray) -> csr_matrix:
        p = x.reshape(-1, 3)
        d = p[a] - p[b]
        u = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-9)
        pairs = csr_matrix((np.c_[u, -u].ravel(), (rows, cols.ravel())), shape=(a.size, 3 * n))
        return vstack([pairs, prior], format="csr")

    fit = least_squares(residuals, template.ravel(), jac=jacobian, tr_solver="lsmr")
    return fit.x.reshape(-1, 3)


def _settled(state: LabelState, anatomy: Anatomy, rate_hz: float) -> list[tuple[str, str]]:
    """Exchange the names of pairs the anatomy finds the wrong way round (and say which)."""
    perm, done = settle_sides(state.name_pos, anatomy, rate_hz, state.params.min_side_confidence)
    if not done:
        return []
    named = state.label_of >= 0
    state.label_of[named] = perm[state.label_of[named]]
    moved = np.empty_like(state.name_pos)
    moved[perm] = state.name_pos
    state.name_pos = moved
    return [(state.names[a], state.names[b]) for a, b in done]


def _second_pass(
    first: LabelState, template: NDArray, segments: tuple, params: TrackingParams
) -> LabelState:
    """A state on ``template`` and ``segments`` holding the first pass' names of long
    pieces, with names spread again."""
    state = LabelState.begin(first.tracks, first.names, template, segments, params)
    state.upright = state.partial = True
    long = first.n_measured >= first.params.min_track_length
    for t in np.flatnonzero((first.label_of >= 0) & long):
        state.name_piece(int(t), int(first.label_of[t]))
    state.rich, state.fit_rms = first.rich, first.fit_rms
    spread(state)
    rematch(state)
    name_groups(state)
    if name_from_trial(state):
        spread(state)
    return state


def label_with_set(
    tracks: Tracks,
    marker_set: MarkerSet,
    params: TrackingParams,
    rate_hz: float,
    template_mm: NDArray | None = None,
    template_upright: bool = False,
) -> Labelling:
    """Name tracks from a shipped marker set, with or without the subject's template.

    Parameters
    ----------
    tracks : Tracks
        Blended pieces (see :func:`~kisscal.tracking.label_tracks`).
    marker_set : MarkerSet
        The set, restricted to the session's names (:meth:`MarkerSet.select`).
    params : TrackingParams
    rate_hz : float
        Field rate (the first window spans ``set_window_s``; the walking direction).
    template_mm : (n, 3) array, optional
        The subject's own template (a static trial, or the session's ``template_mm``);
        without it the set's template is fitted to the subject from the trial.
    template_upright : bool
        ``template_mm`` is in the lab frame, Z up (a static trial's positions): its
        heights above the floor are checked too.

    Without ``template_mm``, the trial's vertical is found from the data (Y up, Z up or
    any lab axis and sign, :func:`~kisscal.tracking.labelling.vertical.upright_rotation`);
    the labelling runs turned upright and the trajectories come back in the lab frame.

    Returns
    -------
    Labelling
        Judged by the set's anatomy (confidence, flagged names); ``height_mm`` is the
        estimated stature when no template was given.

    References
    ----------
    Winter 2009 (segment lengths proportional to stature, which the scaled templates
    assume); Kabsch 1976 and Torgerson 1952 (the matching).

    Examples
    --------
    >>> from kisscal.markersets import marker_set
    >>> from kisscal.synth.motion import walking_trial
    >>> from kisscal.tracking import TrackingParams, track_points, blend_tracks
    >>> m = walking_trial(2, 150, 50.0, path_mm=3500, model="grounded", height_m=1.6,
    ...                   heading_deg=230)
    >>> f, k = np.nonzero(np.isfinite(m.xyz_mm[..., 0]))
    >>> pieces = blend_tracks(track_points(f, m.xyz_mm[f, k], TrackingParams()), TrackingParams())
    >>> found = label_with_set(pieces, marker_set("kiss"), TrackingParams(), 50.0)
    >>> t = found.tracks  # each trajectory's first sample is its true marker's
    >>> right = [np.allclose(t.xyz_mm[t.track == i][0],
    ...                      m.xyz_mm[t.field[t.track == i][0], m.names.index(name)])
    ...          for i, name in enumerate(found.labels)]
    >>> len(right), all(right), found.certain, bool(abs(found.height_mm - 1600) <= 100)
    (15, True, True, True)
    """
    names, segments = marker_set.names, marker_set.segments
    if template_mm is not None:
        template = np.asarray(template_mm, dtype=float)
        found = label_tracks(tracks, names, params, template, segments)
        anatomy = Anatomy.of_set(marker_set, template, heights=template_upright)
        return judge_sides(found, anatomy, template, rate_hz, params)
    window = max(round(params.set_window_s * rate_hz), 10)
    first_params = params.replace(label_window_fields=min(params.label_window_fields, window))
    up = upright_rotation(tracks, marker_set, first_params)
    if not np.array_equal(up, np.eye(3)):
        # The trial's vertical is not lab Z: label it turned upright, give it back as it was.
        found = _label_upright(turned(tracks, up), marker_set, params, rate_hz, first_params)
        return replace(found, tracks=turned(found.tracks, up.T))
    return _label_upright(tracks, marker_set, params, rate_hz, first_params)


def _label_upright(
    tracks: Tracks,
    marker_set: MarkerSet,
    params: TrackingParams,
    rate_hz: float,
    first_params: TrackingParams,
) -> Labelling:
    """:func:`label_with_set` without a template, on pieces whose vertical is Z."""
    names, segments = marker_set.names, marker_set.segments
    height, partial = estimate_height(tracks, marker_set, first_params)
    if not np.isfinite(height):
        return generic(tracks, params, names, float("nan"))
    first = first_pass(tracks, marker_set, first_params, height)
    if first is None:
        return replace(generic(tracks, params, names, float("nan")), height_mm=height)
    fitted = height
    if partial and height == PARTIAL_HEIGHTS_MM[0]:
        # A part stood on the floor fits many statures (partial.py): at the adult bound
        # the stature is judged by the set's segments its names hold rigid.
        height, first = rigid_height(first, marker_set, first_params, height)
    scaled_set = marker_set.scaled(height)
    scaled = scaled_set.template_mm
    anatomy = Anatomy.of_set(scaled_set)
    exchanged = _settled(first, anatomy, rate_hz)
    template = fit_template(first.name_pos, scaled, segment_mask(names, segments))
    second = _second_pass(first, template, segments, params)
    settle_feet(second, scaled)
    if name_by_segment(second):  # the feet settled: their markers' segments hold
        spread(second)
    found = replace(join(second), height_mm=height)

    def judge(labelling: Labelling) -> Labelling:
        # What the labelling itself doubted (a foot's near ties) stays doubtful.
        own = replace(labelling, flagged=found.flagged)
        return judge_sides(own, anatomy, template, rate_hz, params, scaled)

    judged = regive_doubted(judge(found), anatomy, scaled, judge, segment_mask(names, segments))
    judged = replace(judged, exchanged=tuple(exchanged) + judged.exchanged)
    if partial and judged.fits_marker_set:
        # A part fits many statures, and a wrong one shifts names along the limbs where
        # nothing above flags them (partial.py): the set's segments must vouch for each.
        judged = _doubting(judged, names, unvouched(judged, marker_set))
    if judged.fits_marker_set:
        # A foot's markers stay rigid whatever their names: the walk orders them
        # (footorder.py), a heel's name with a foot marker behind it is doubted.
        judged = _doubting(judged, names, out_of_order_feet(judged, scaled_set, anatomy, rate_hz))
    tried = PARTIAL_HEIGHTS_MM if partial else HEIGHTS_MM
    bound = fitted in (tried[0], tried[-1]) or height != fitted
    if (bound or not _floor_seen(judged, scaled_set, params)) and judged.fits_marker_set:
        # The floor fit's stature is a bound of the plausible range (the template fits
        # this trial at no plausible stature), or the segments chose another; or no name
        # stands near the floor, whose height was then assumed: nothing named is certain.
        taken = set(judged.labels)
        return replace(judged, flagged=tuple(n for n in names if n in taken))
    return judged


def _floor_seen(labelling: Labelling, marker_set: MarkerSet, params: TrackingParams) -> bool:
    """Whether a name of ``labelling`` lies within ``label_tolerance_mm`` of the set's
    lowest template height: without one (an upper body, shd01) the heights were judged
    from a floor assumed (:func:`~kisscal.tracking.labelling.upright.fit_on_floor`), and
    a head turned on the trunk can be named a quarter turn round by its place."""
    unnamed = set(labelling.unlabelled)
    held = [
        marker_set.names.index(lab)
        for t, lab in enumerate(labelling.labels)
        if t not in unnamed and lab in marker_set.names
    ]
    z = marker_set.template_mm[:, 2]
    return bool(held) and float(z[held].min()) <= z.min() + params.label_tolerance_mm


def _doubting(labelling: Labelling, names: Sequence[str], doubted: Iterable[str]) -> Labelling:
    """``labelling`` with ``doubted`` names flagged too, in the set's order."""
    doubt = set(labelling.flagged) | set(doubted)
    return replace(labelling, flagged=tuple(n for n in names if n in doubt))
