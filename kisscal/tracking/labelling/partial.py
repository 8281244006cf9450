"""The stature of a part of a set judged by the rigidity of the segments it names.

A part of the set (a lower body, markers of another set beside it) stood on the floor
fits the scaled template of many statures about as well (issue 26: sample14's 1.45 m
subject and 2198928's child of 0.90 m both fitted best at the adult range's bound,
1.40 m), and the names a wrong stature gives are shifted along the limbs: a thigh's
name on the ASIS, the knee's on the thigh marker. Such names break the set's rigid
segments over the trial (the ASIS and the thigh marker move apart as the hip flexes),
while right names hold them (the thigh and knee markers keep their distance). So when
the floor fit sits at its bound, the first pass is run at statures across the whole
range and the one whose names hold the most segments rigid is kept.

Away from the bound the fit can be wrong too (issue 26: a 1.0-1.2 m child's lower body
fitted 1.45-1.75 m, the thigh's name on the ASIS and the knee's on the thigh marker), and
judging every stature there costs a first pass each and re-names right parts (a tennis
serve's head holds its segments under any order of names). So the names a part ends
with are vouched for by the set's segments instead (:func:`unvouched`). Shifted names
break the segment they name across a joint (ASIS to thigh marker, 13-18 mm SD over a
walk), or leave it unseen beside the unnamed marker they were shifted from (the knee's
name on the thigh marker, the knee marker unnamed and rigid to it).
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray

from kisscal.markersets.model import MarkerSet
from kisscal.tracking.labelling.core import crowded
from kisscal.tracking.labelling.label import name_pieces
from kisscal.tracking.labelling.result import Labelling
from kisscal.tracking.labelling.state import (
    MIN_SHARED_FIELDS,
    RIGID_SPREAD_MM,
    LabelState,
    segment_mask,
)
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import MEASURED, Tracks

#: Statures (mm) whose first pass is judged when the floor fit of a part sits at its
#: bound: the whole range, every 100 mm (segment lengths tell 10 cm apart).
JUDGED_HEIGHTS_MM = np.arange(800.0, 2001.0, 100.0)
#: A stature replaces the floor fit's when its names hold at least this many more
#: segments rigid (net of the segments they break): one pair of markers on one body
#: segment holds rigid under any two names of a segment, by chance.
MIN_SEGMENT_GAIN = 2
#: A segment vouches for its two names when their distance keeps an SD under this (mm)
#: over the trial, and breaks them above it: twice the rigid spread, as real pelvises,
#: thighs, shanks and feet keep 1-5 mm through skin motion where names shifted across a
#: joint spread 13 mm and more.
VOUCH_SPREAD_MM = 2.0 * RIGID_SPREAD_MM


def segment_score(
    name_pos: NDArray, template: NDArray, rigid: NDArray, min_shared: int = MIN_SHARED_FIELDS
) -> tuple[int, int, float]:
    """How well named trajectories hold the set's rigid segments.

    Parameters
    ----------
    name_pos : (n, n_fields, 3) array
        Each name's trajectory (NaN where not held).
    template : (n, 3) array
        The set's template at the stature judged.
    rigid : (n, n) bool array
        The set's segments (:func:`~kisscal.tracking.labelling.state.segment_mask`).
    min_shared : int
        Fields two names must share for their segment to be judged.

    Returns
    -------
    held : int
        Segments whose two names keep their distance (SD under the rigid spread, 5 mm).
    broken : int
        Segments whose two names are seen together but not rigidly.
    misfit : float
        RMS log ratio of the held segments' median lengths to the template's (inf when
        none is held): a stature's segments have its lengths (Winter 2009).
    """
    a, b = np.nonzero(np.triu(rigid, 1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # pairs never seen together
        d = np.linalg.norm(name_pos[a] - name_pos[b], axis=2)
        count = np.isfinite(d).sum(axis=1)
        sd = np.nanstd(d, axis=1)
        length = np.nanmedian(d, axis=1)
    seen = count >= min_shared
    held = seen & (sd < RIGID_SPREAD_MM)
    broken = int((seen & ~held).sum())
    if not held.any():
        return 0, broken, np.inf
    ratio = length[held] / np.linalg.norm(template[a[held]] - template[b[held]], axis=1)
    return int(held.sum()), broken, float(np.sqrt(np.mean(np.log(ratio) ** 2)))


def first_pass(
    tracks: Tracks, marker_set: MarkerSet, params: TrackingParams, height_mm: float
) -> LabelState | None:
    """Phases 1-5 on the set's template scaled to ``height_mm``, without segments (their
    lengths are the subject's); None when no body is matched."""
    scaled = marker_set.scaled(height_mm).template_mm
    state = LabelState.begin(tracks, marker_set.names, scaled, None, params)
    if state is None:
        return None
    state.upright = state.partial = True
    return state if name_pieces(state) else None


def _rank(state: LabelState, marker_set: MarkerSet) -> tuple[int, float]:
    """(held - broken segments, -misfit) of a first pass' names."""
    rigid = segment_mask(marker_set.names, marker_set.segments)
    held, broken, misfit = segment_score(state.name_pos, state.template, rigid)
    return held - broken, -misfit


def rigid_height(
    first: LabelState, marker_set: MarkerSet, params: TrackingParams, height_mm: float
) -> tuple[float, LabelState]:
    """The stature, and its first pass, whose names hold the most segments rigid.

    ``first`` is the first pass at ``height_mm``, the floor fit's stature. The first
    pass runs at each of :data:`JUDGED_HEIGHTS_MM`; the one holding the most segments
    net of those it breaks (then whose held lengths fit its template best) replaces
    ``first`` when it holds :data:`MIN_SEGMENT_GAIN` more.
    """
    own = _rank(first, marker_set)
    best, best_height, best_state = own, height_mm, first
    for height in JUDGED_HEIGHTS_MM[JUDGED_HEIGHTS_MM != height_mm]:
        state = first_pass(first.tracks, marker_set, params, float(height))
        if state is not None and _rank(state, marker_set) > best:
            best, best_height, best_state = _rank(state, marker_set), float(height), state
    if best[0] >= own[0] + MIN_SEGMENT_GAIN:
        return best_height, best_state
    return height_mm, first


def _dense(labelling: Labelling, row_of_track: NDArray, n_rows: int) -> NDArray[np.float64]:
    """Measured samples (n_rows, n_fields, 3) of the tracks ``row_of_track`` maps to a row
    (-1: none); NaN elsewhere."""
    tr = labelling.tracks
    n_fields = int(tr.field.max()) + 1 if tr.field.size else 0
    pos = np.full((n_rows, n_fields, 3), np.nan)
    if row_of_track.size == 0:
        return pos
    row = row_of_track[tr.track]
    keep = (tr.status == MEASURED) & (row >= 0)
    pos[row[keep], tr.field[keep]] = tr.xyz_mm[keep]
    return pos


def named_positions(labelling: Labelling, names: tuple[str, ...]) -> NDArray[np.float64]:
    """Each of ``names``' measured trajectory (n, n_fields, 3) in ``labelling`` (NaN
    where not measured or not named)."""
    index = {name: i for i, name in enumerate(names)}
    unnamed = set(labelling.unlabelled)
    of_track = [
        -1 if t in unnamed else index.get(lab, -1) for t, lab in enumerate(labelling.labels)
    ]
    return _dense(labelling, np.array(of_track, dtype=np.int64), len(names))


def unnamed_positions(labelling: Labelling) -> NDArray[np.float64]:
    """The unnamed trajectories' measured samples (u, n_fields, 3)."""
    row = np.full(len(labelling.labels), -1, dtype=np.int64)
    unnamed = np.array(sorted(labelling.unlabelled), dtype=np.int64)
    row[unnamed] = np.arange(unnamed.size)
    return _dense(labelling, row, unnamed.size)


def _rigid_to_unnamed(one: NDArray, unnamed: NDArray, min_shared: int) -> bool:
    """Whether an unnamed trajectory keeps its distance to ``one`` (n_fields, 3): an SD
    under :data:`VOUCH_SPREAD_MM` over at least half of ``one``'s fields (a short
    piece beside any marker looks rigid)."""
    if unnamed.shape[0] == 0:
        return False
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # pieces never seen with it
        d = np.linalg.norm(unnamed - one[None], axis=2)
        sd = np.nanstd(d, axis=1)
    shared = np.isfinite(d).sum(axis=1)
    enough = max(min_shared, np.isfinite(one[:, 0]).sum() // 2)
    return bool(((shared >= enough) & (sd < VOUCH_SPREAD_MM)).any())


def unvouched(
    labelling: Labelling, marker_set: MarkerSet, min_shared: int = MIN_SHARED_FIELDS
) -> tuple[str, ...]:
    """Names of ``labelling`` that the set's segments do not vouch for.

    A segment vouches for its two names when they are seen together in ``min_shared``
    fields and their distance keeps an SD under :data:`VOUCH_SPREAD_MM`; it breaks them
    when it spreads more. A name is unvouched when a segment breaks it, or when none
    vouches for it while an unnamed trajectory keeps a rigid distance to it: that one is
    its segment's partner left unnamed, or the marker whose name it took when the names
    are shifted along the limb (see module). A name with no partner in the trial, and no
    rigid unnamed neighbour, has nothing to be shifted onto from. Among markers of another
    set (more trajectories seen at once than the set has names, :func:`crowded`: clusters
    on the thigh and shank are rigid with the knee and ankle markers) a vouching segment
    proves nothing when an unnamed trajectory keeps rigid to the name too: names shifted
    along the limb onto those markers hold the segment as rigidly (issue 26: pyCGM's
    Movement_trial, the thigh's name on the knee marker and the knee's on a shank
    cluster marker, 5.5 mm SD).

    References
    ----------
    Shafiq et al. 2001 (rigid segment lengths as a check on a marker's identity).
    """
    names = marker_set.names
    pos = named_positions(labelling, names)
    a, b = np.nonzero(np.triu(segment_mask(names, marker_set.segments), 1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # pairs never seen together
        d = np.linalg.norm(pos[a] - pos[b], axis=2)
        sd = np.nanstd(d, axis=1)
    seen = np.isfinite(d).sum(axis=1) >= min_shared
    vouch, broken = seen & (sd < VOUCH_SPREAD_MM), seen & (sd >= VOUCH_SPREAD_MM)
    n = len(names)
    vouched = np.bincount(np.r_[a[vouch], b[vouch]], minlength=n) > 0
    breaks = np.bincount(np.r_[a[broken], b[broken]], minlength=n) > 0
    held = np.isfinite(pos[..., 0]).any(axis=1)
    others = unnamed_positions(labelling)
    at_once = np.isfinite(pos[..., 0]).sum(axis=0) + np.isfinite(others[..., 0]).sum(axis=0)
    many = at_once.any() and crowded(int(np.median(at_once[at_once > 0])), n)
    return tuple(
        name
        for i, name in enumerate(names)
        if held[i]
        and (
            breaks[i]
            or ((many or not vouched[i]) and _rigid_to_unnamed(pos[i], others, min_shared))
        )
    )
