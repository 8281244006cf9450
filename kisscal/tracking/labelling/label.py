"""The labelling's entry point: :func:`label_tracks` runs the phases in order."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from kisscal.errors import InputError
from kisscal.tracking.labelling.feet import settle_feet
from kisscal.tracking.labelling.groups import name_groups
from kisscal.tracking.labelling.learned import name_from_trial
from kisscal.tracking.labelling.pelvis import settle_pelvis_offsets, settle_pelvis_pieces
from kisscal.tracking.labelling.result import Labelling, generic, join
from kisscal.tracking.labelling.spread import rematch, spread
from kisscal.tracking.labelling.state import LabelState
from kisscal.tracking.labelling.unseen import name_unseen
from kisscal.tracking.labelling.window import match_first_window
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import Tracks


def label_tracks(
    tracks: Tracks,
    names: tuple[str, ...] | list[str] | None,
    params: TrackingParams,
    template_mm: ArrayLike | None = None,
    segments: list[tuple[str, str]] | tuple | None = None,
) -> Labelling:
    """Name tracks from the marker set (DESIGN.md ``[markers]``).

    The phases, each a function on a :class:`~kisscal.tracking.labelling.state.LabelState`:
    match the window where most long pieces are seen to the template; spread names
    through rigid partners; match again the windows where unnamed long pieces remain;
    name groups of pieces that entered the view together; name long pieces left without a
    partner by the distances the trial showed, and pieces of names the trial never
    showed by the template's; name a long piece that two names' rigid partners allow
    alike by the trajectory it continues; give each foot's names the way the
    distances to the shank and the walk find far better
    (:func:`~kisscal.tracking.labelling.feet.settle_feet`); join pieces sharing a name.

    Parameters
    ----------
    tracks : Tracks
        Blended track pieces, short ones included: a short piece that fits a name joins
        that name's trajectory, one that fits none is dropped (Shafiq et al. 2001's
        clean-up of ghost tracks, ``min_track_length``); long pieces that fit none are
        reported.
    names : sequence of str or None
        Marker names. Without names or without a template, tracks are named M1, M2, ...
    params : TrackingParams
        ``label_tolerance_mm``, ``label_segment_tolerance_mm``, ``label_fields``,
        ``min_label_fraction``, ``min_label_points``, ``min_body_fit_points``.
    template_mm : (n, 3) array, optional
        Marker positions in a standing pose, same order as ``names``, any frame.
    segments : sequence of (str, str), optional
        Pairs of names on one rigid segment; added to the pairs found rigid in the data.

    Returns
    -------
    Labelling

    References
    ----------
    Shafiq et al. 2001 (clean-up of short ghost tracks); Torgerson 1952 and Kabsch 1976
    (the average pose and its rigid fits, :mod:`kisscal.tracking.rigid`).
    """
    if not names or template_mm is None or tracks.n_tracks == 0:
        return generic(tracks, params, tuple(names or ()), float("nan"))
    names = tuple(names)
    template = np.asarray(template_mm, dtype=float)
    if template.shape != (len(names), 3):
        raise InputError(
            f"markers: template_mm needs one [x, y, z] per name ({len(names)}), "
            f"got shape {template.shape}"
        )
    if len(set(names)) != len(names):
        raise InputError("markers: names must be unique")
    state = LabelState.begin(tracks, names, template, segments, params)
    if state is None:
        return generic(tracks, params, names, float("nan"))
    if not name_pieces(state):
        return generic(tracks, params, names, state.fit_rms)
    settle_feet(state, state.template)
    return join(state)


def name_pieces(state: LabelState) -> bool:
    """Phases 1 to 5 on ``state``; the feet are settled after the first window and
    after the first spreading (a foot named the wrong way round would hand its ankle's
    pieces the tibia's name as names spread, which the last contest cannot take back)
    and again, by :func:`label_tracks`, after the last naming pass. False when the first
    window matches no body."""
    if not match_first_window(state):
        return False
    settle_feet(state, state.template)
    spread(state)
    settle_feet(state, state.template)
    rematch(state)
    name_groups(state)
    if name_from_trial(state):
        spread(state)
    if name_unseen(state):
        spread(state)
    spread(state, continuity=True)
    # A body fit from the legs alone can name the sacrum an ASIS (pelvis.py).
    if settle_pelvis_offsets(state):
        spread(state, continuity=True)
    # A first window can name an ASIS and the sacrum the other way round (pelvis.py).
    settle_pelvis_pieces(state)
    return True
