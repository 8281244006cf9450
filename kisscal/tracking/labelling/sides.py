"""The last word on left and right: a finished labelling judged by the anatomy.

Pairs the anatomy finds the wrong way round are exchanged, every name gets a confidence,
and names that nothing tells apart from their mirror partner are flagged
(:func:`judge_sides`).
"""

from __future__ import annotations

from dataclasses import replace
from types import MappingProxyType

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.anatomy import (
    Anatomy,
    check_anatomy,
    feet_against_pelvis,
    floor_height,
    forward_directions,
    settle_sides,
)
from kisscal.tracking.labelling.result import Labelling
from kisscal.tracking.labelling.runnerup import (
    chained,
    mirror_rows,
    name_fits,
    name_margins,
    strays,
    turned_round,
    uneven_legs,
)
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rigid import field_fits

#: Below this mirror-fit ratio the template fit alone cannot tell left from right.
MIRROR_MARGIN = 1.05
_FIT_FIELDS = 40


def name_positions(labelling: Labelling, names: tuple[str, ...]) -> NDArray[np.float64]:
    """Trajectory of each name (n, F, 3), NaN where a name is not seen or not taken."""
    dense = labelling.tracks.positions()
    out = np.full((len(names), dense.shape[1], 3), np.nan)
    row = {n: i for i, n in enumerate(names)}
    for t, label in enumerate(labelling.labels):
        if label in row:
            out[row[label]] = dense[t]
    return out


def mirror_fit_ratio(pos: NDArray, template: NDArray, pairs: tuple) -> float:
    """Median rigid-fit RMS of the mirrored labelling over that of the labelling itself,
    over up to 40 of the fields where most names are seen."""
    if not pairs:
        return float("nan")
    seen = np.isfinite(pos[..., 0])
    count = seen.sum(axis=0)
    fields = np.flatnonzero(count >= max(3, 0.8 * count.max()))
    fields = fields[np.linspace(0, fields.size - 1, min(_FIT_FIELDS, fields.size)).astype(int)]
    rows = np.flatnonzero(seen[:, fields].any(axis=1))
    mirror = np.arange(pos.shape[0])
    for a, b in pairs:
        mirror[a], mirror[b] = b, a
    own = field_fits(pos, fields, rows, rows, template)
    other = field_fits(pos, fields, rows, mirror[rows], template)
    if not own.size:
        return float("nan")
    return float(np.median(other) / max(float(np.median(own)), 1e-9))


def doubted(
    pos: NDArray, anatomy: Anatomy, reference: NDArray, params: TrackingParams
) -> NDArray[np.bool_]:
    """Per name, whether the evidence the labelling did not shape doubts it
    (:mod:`~kisscal.tracking.labelling.runnerup`): another name fits its trajectory
    better by ``name_deficit_fraction`` of stature, a name no trajectory holds by
    ``free_deficit_fraction`` (by any margin when none of its template neighbours is
    held and the free name's group is: :func:`~kisscal.tracking.labelling.runnerup.strays`),
    or it is a leg's not level with the other leg."""
    floor = floor_height(pos, anatomy)
    stature = float(np.ptp(reference[:, 2]))
    args = (pos, reference, anatomy.heights_mm, floor, anatomy.pairs)
    with np.errstate(invalid="ignore"):
        out = name_margins(*args) < -params.name_deficit_fraction * stature
        out |= name_margins(*args, among_free=True) < -params.free_deficit_fraction * stature
    out |= strays(*args)
    if anatomy.heights_mm is not None:
        out |= uneven_legs(pos, anatomy.heights_mm, anatomy.pairs, anatomy.front + anatomy.back)
    return out


def _turned(
    labelling: Labelling,
    pos: NDArray,
    anatomy: Anatomy,
    reference: NDArray,
    rate_hz: float,
    params: TrackingParams,
    doubtful: set[str],
) -> set[str]:
    """Names of front/back pairs held alone that an unnamed trajectory, or one whose
    name is ``doubtful``, finds turned round
    (:func:`~kisscal.tracking.labelling.runnerup.turned_round`).

    A doubted name is no evidence of where its marker belongs: Vicon_analysis without
    arms had C7's name on the clavicle marker and the true C7 marker named LBHD (a head
    name alone, doubted); only C7's marker, behind the clavicle's, says the trunk's back
    name sits on its front marker. A doubted marker that its own name puts where it is
    (a toe ahead of its ankle, the heel free) is no evidence."""
    rows = [i for i, n in enumerate(anatomy.names) if n in doubtful]
    if not anatomy.ahead or not (labelling.unlabelled or rows):
        return set()
    spare = labelling.tracks.positions()[list(labelling.unlabelled)]
    spare = np.concatenate([spare, pos[rows]])
    spare_names = np.r_[np.full(len(labelling.unlabelled), -1), rows].astype(int)
    forward = forward_directions(pos, anatomy, rate_hz)[0]
    args = (anatomy.ahead, reference, forward, params.min_side_confidence, spare_names)
    return {anatomy.names[i] for i in np.flatnonzero(turned_round(pos, spare, *args))}


def _chained(
    pos: NDArray, anatomy: Anatomy, reference: NDArray, params: TrackingParams, doubtful: set
) -> set[str]:
    """Names the doubt of ``doubtful`` reaches along the names trajectories prefer by
    ``free_deficit_fraction`` of stature
    (:func:`~kisscal.tracking.labelling.runnerup.chained`): a name whose holder is
    doubted is as good as free."""
    names = anatomy.names
    fits = name_fits(pos, reference, anatomy.heights_mm, floor_height(pos, anatomy))
    seed = np.isin(names, list(doubtful))
    margin = params.free_deficit_fraction * float(np.ptp(reference[:, 2]))
    out = chained(fits, mirror_rows(len(names), anatomy.pairs), seed, margin)
    return {names[i] for i in np.flatnonzero(out)}


def _relabelled(labelling: Labelling, names: tuple[str, ...], perm: NDArray) -> tuple[str, ...]:
    row = {n: i for i, n in enumerate(names)}
    return tuple(names[perm[row[lab]]] if lab in row else lab for lab in labelling.labels)


def judge_sides(
    labelling: Labelling,
    anatomy: Anatomy,
    template: NDArray,
    rate_hz: float,
    params: TrackingParams,
    reference: NDArray | None = None,
) -> Labelling:
    """``labelling`` with left and right settled by ``anatomy`` and its confidence.

    Parameters
    ----------
    labelling : Labelling
        A finished labelling (names of ``anatomy.names``).
    anatomy : Anatomy
        What the names are (mirror pairs, pelvis, feet, vertical order).
    template : (n, 3) array
        The template the labelling used, rows as ``anatomy.names`` (for the mirror fit).
    rate_hz : float
        Field rate: the walking direction is smoothed over a fixed time.
    params : TrackingParams
        ``min_side_confidence``, ``name_deficit_fraction``, ``free_deficit_fraction``.
    reference : (n, 3) array, optional
        A template the labelling did not shape (the set's, scaled to the subject), rows
        as ``anatomy.names``: a name that another name fits clearly better against it
        (:func:`doubted`) is flagged, and so is one that a doubt reaches along a chain of
        names shifted one marker (:func:`_chained`). Default ``template``.

    Returns
    -------
    Labelling
        With ``confidence``, ``flagged``, ``exchanged``, ``mirror_fit_ratio`` and
        ``sides_from`` set; labels of exchanged pairs swapped.
    """
    if not labelling.fits_marker_set:
        return labelling
    names = anatomy.names
    pos = name_positions(labelling, names)
    perm, done = settle_sides(pos, anatomy, rate_hz, params.min_side_confidence)
    moved = np.empty_like(pos)
    moved[perm] = pos
    check = check_anatomy(moved, anatomy, rate_hz)
    ratio = mirror_fit_ratio(moved, template, anatomy.pairs)
    confidence = {
        n: float(c) for n, c in zip(names, check.confidence, strict=True) if np.isfinite(c)
    }
    flagged = {n for n, c in confidence.items() if c < params.min_side_confidence}
    # What the labelling itself doubted (a foot named among near ties) stays doubtful.
    flagged |= {names[perm[names.index(n)]] for n in labelling.flagged if n in names}
    ref = template if reference is None else reference
    flagged |= {names[i] for i in np.flatnonzero(doubted(moved, anatomy, ref, params))}
    # A doubted marker's place is weighed in the set's frame (x forward, z up): only
    # against the set's own template.
    doubtful = flagged if reference is not None else set()
    flagged |= _turned(labelling, moved, anatomy, ref, rate_hz, params, doubtful)
    flagged |= _chained(moved, anatomy, ref, params, flagged)
    paired = {names[i] for pair in anatomy.pairs for i in pair}
    judged = check.forward != "none" and any(n in confidence for n in paired)
    # A body that does not walk, its pelvis named facing against its feet: part of it is
    # named turned round (a still mid-stride pose fits the template better so), and
    # nothing tells which part: no side and no pelvis name is certain.
    against = check.forward == "none" and feet_against_pelvis(moved, anatomy)
    if (not judged and not ratio >= MIRROR_MARGIN) or against:
        pelvis = {names[i] for i in anatomy.front + anatomy.back} if against else set()
        flagged |= (paired | pelvis) & set(_relabelled(labelling, names, perm))
    # Names nothing tells apart from a close neighbour (a wrist bar's ends) are uncertain.
    flagged |= {names[i] for pair in anatomy.twins for i in pair} & set(labelling.labels)
    labels, row = _relabelled(labelling, names, perm), {n: i for i, n in enumerate(names)}
    return replace(
        labelling,
        labels=labels,
        # an exchanged pair whose one name no track held moves its absence too (kiss 3
        # seed 414: the left knee named RKNE, exchanged, and RKNE never placed as absent)
        missing=tuple(names[perm[row[n]]] if n in row else n for n in labelling.missing),
        confidence=MappingProxyType(confidence),
        flagged=tuple(n for n in names if n in flagged),
        exchanged=tuple((names[a], names[b]) for a, b in done),
        mirror_fit_ratio=ratio,
        sides_from="anatomy" if judged else "fit",
    )
