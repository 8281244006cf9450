"""Left and right settled by anatomy, and how sure each name is.

Distances cannot tell a body from its mirror image, and a rigid fit to a template only
weakly when the template is another pose or another person. The body can: a subject
walks forward, up is up (lab Z), so the subject's left is ``up x forward``; a marker
named left (``LKNE``) must lie on that side of its right partner (``RKNE``) in nearly every
field, anterior pelvis markers lie ahead of posterior ones, and feet lie well below
knees, knees well below hips.

:class:`Anatomy` holds what a marker set (or, failing one, the ``L``/``R`` naming
convention) says about the names; :func:`check_anatomy` measures, per name, the fraction
of fields where the labelled trajectories agree with it. A left/right pair found the
wrong way round in nearly every field is exchanged (:func:`settle_sides`); a name whose
agreement is below ``min_side_confidence`` is flagged, never written as certain.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import gaussian_filter1d

from kisscal.markersets.model import MarkerSet
from kisscal.tracking.labelling.pelvis import lone_wrong_side, pelvis_roles, settle_pelvis
from kisscal.tracking.labelling.runnerup import TEMPLATE_NEIGHBOURS

#: Marker pairs at least this far apart in the template's height, as a fraction of
#: stature, are checked for their vertical order (knee above ankle, hip above knee).
ABOVE_FRACTION = 0.2
#: ... and pairs on one side (or one segment, front to back) at least this far apart.
NEAR_FRACTION = 0.04
#: A marker's height above the floor may stray this far (fraction of stature) from its
#: template height: a heel rises in swing, a hand swings.
HEIGHT_FRACTION = 0.15
#: A field is not standing when this percentage of the names (or more) sit over half
#: the height tolerance below (or above) their template heights (:func:`_near_height`).
STANDING_QUANTILE = 25.0
#: A subject whose pelvis moves slower than this (mm/s) is standing, not walking.
WALKING_MM_S = 150.0
#: The walking direction is the pelvis velocity smoothed over this (s, Gaussian SD).
DIRECTION_S = 0.4
#: A moving subject's direction of travel is its forward only when it agrees with the
#: pelvis' back-to-front direction in at least this fraction of the fields, or disagrees
#: in as many (a pelvis named back to front, which the walk must reveal). Between the
#: two the subject moves otherwise than forward, and the pelvis tells: walks agree in
#: 100 % of the fields (the regression set's), a tennis serve in 52 % (steps sideways
#: and back).
ALONG_FRACTION = 2 / 3


@dataclass(frozen=True)
class Anatomy:
    """What is known about a set of names, as rows of ``names``.

    Attributes
    ----------
    names : tuple of str
    pairs : tuple of (int, int)
        (left, right) mirror pairs.
    front, back : tuple of int
        Pelvis markers ahead of and behind the hip joints (ASIS; PSIS, sacrum).
    heel, toe : tuple of int
        Heel and toe markers (both sides).
    above : tuple of (int, int)
        (upper, lower) pairs far apart in height (see :data:`ABOVE_FRACTION`), or apart
        on one side of the body (:data:`NEAR_FRACTION`): thigh above knee, knee above
        shank, shank above ankle.
    ahead : tuple of (int, int)
        (front, back) pairs of one segment (or across a hinge) apart along the body's
        forward axis (:data:`NEAR_FRACTION`): toe ahead of heel, ankle ahead of heel.
    heights_mm : (n,) array or None
        Template height of each name above the floor (an upright template), and
    height_tolerance_mm : float
        how far from it a marker may be (:data:`HEIGHT_FRACTION` of stature).
    twins : tuple of (int, int)
        Names of one side closer in the template than :data:`NEAR_FRACTION` of stature
        with no check between them (a wrist bar's two ends): nothing here tells them
        apart, so their names are never certain.
    neighbours : tuple of (int, int) or None
        Pairs of names one of which is among the other's
        :data:`~kisscal.tracking.labelling.runnerup.TEMPLATE_NEIGHBOURS` nearest in the
        template: the only names of one side or segment :func:`settle_sides` exchanges
        (None: any).
    """

    names: tuple[str, ...]
    pairs: tuple[tuple[int, int], ...] = ()
    front: tuple[int, ...] = ()
    back: tuple[int, ...] = ()
    heel: tuple[int, ...] = ()
    toe: tuple[int, ...] = ()
    above: tuple[tuple[int, int], ...] = ()
    ahead: tuple[tuple[int, int], ...] = ()
    heights_mm: NDArray[np.float64] | None = None
    height_tolerance_mm: float = float("nan")
    twins: tuple[tuple[int, int], ...] = ()
    neighbours: tuple[tuple[int, int], ...] | None = None

    @classmethod
    def of_names(cls, names: tuple[str, ...]) -> Anatomy:
        """Mirror pairs and pelvis roles by the naming convention alone: ``L<x>`` and
        ``R<x>``; ``*ASI*`` ahead of ``*PSI*`` and ``SACR``
        (:func:`~kisscal.tracking.labelling.pelvis.pelvis_roles`)."""
        index = {n: i for i, n in enumerate(names)}
        pairs = tuple(
            (i, index["R" + n[1:]])
            for i, n in enumerate(names)
            if n.startswith("L") and len(n) > 1 and "R" + n[1:] in index
        )
        front, back = pelvis_roles(tuple(names))
        return cls(tuple(names), pairs, front=front, back=back)

    @classmethod
    def of_set(
        cls, marker_set: MarkerSet, template_mm: NDArray | None = None, heights: bool = True
    ) -> Anatomy:
        """Everything the set knows: its mirror pairs, pelvis and foot roles, heights.

        ``template_mm`` (the subject's own, Z up, e.g. from a static trial) replaces the
        set's heights; the set (scaled to the subject) gives them otherwise; without
        ``heights`` (the stature is unknown) they are not checked.
        """
        names = marker_set.names
        index = {n: i for i, n in enumerate(names)}
        pairs = tuple((index[a], index[b]) for a, b in marker_set.mirror)
        pelvis = [index[n] for n in marker_set.pelvis if n in index]
        x = marker_set.template_mm[:, 0]
        centre = float(np.mean(x[pelvis])) if pelvis else 0.0
        feet = [marker_set.foot(side) for side in ("left", "right")]
        above, ahead = _above(marker_set), _ahead(marker_set)
        return cls(
            tuple(names),
            pairs,
            front=tuple(i for i in pelvis if x[i] > centre),
            back=tuple(i for i in pelvis if x[i] <= centre),
            heel=tuple(index[f["heel"]] for f in feet if "heel" in f),
            toe=tuple(index[f["toe"]] for f in feet if "toe" in f),
            above=above,
            ahead=ahead,
            heights_mm=_heights(marker_set, template_mm) if heights else None,
            height_tolerance_mm=HEIGHT_FRACTION * marker_set.height_mm,
            twins=_twins(marker_set, pairs, above + ahead),
            neighbours=_neighbours(marker_set.template_mm),
        )


def _heights(marker_set: MarkerSet, template_mm: NDArray | None) -> NDArray[np.float64]:
    z = marker_set.template_mm[:, 2]
    if template_mm is None:
        return z.copy()
    own = np.asarray(template_mm, dtype=float)[:, 2]
    return own - own.min() + z.min()


def _above(marker_set: MarkerSet) -> tuple[tuple[int, int], ...]:
    z = marker_set.template_mm[:, 2]
    side = np.zeros(len(marker_set.names))
    index = {n: i for i, n in enumerate(marker_set.names)}
    for a, b in marker_set.mirror:
        side[index[a]], side[index[b]] = 1.0, -1.0
    gap = z[:, None] - z[None, :]
    one_side = (side[:, None] == side[None, :]) & (side[:, None] != 0)
    height = marker_set.height_mm
    pick = (gap > ABOVE_FRACTION * height) | (one_side & (gap > NEAR_FRACTION * height))
    return tuple((int(i), int(j)) for i, j in zip(*np.nonzero(pick), strict=True))


def _twins(marker_set: MarkerSet, pairs: tuple, checked: tuple) -> tuple[tuple[int, int], ...]:
    """Pairs of names closer in the template than :data:`NEAR_FRACTION` of stature, not
    mirror partners, that no vertical or front/back check involves together."""
    t = marker_set.template_mm
    d = np.linalg.norm(t[:, None] - t[None, :], axis=2)
    apart = {frozenset(p) for p in pairs} | {frozenset(p) for p in checked}
    close = np.triu(d < NEAR_FRACTION * marker_set.height_mm, 1)
    return tuple(
        (int(i), int(j)) for i, j in zip(*np.nonzero(close), strict=True) if {i, j} not in apart
    )


def _neighbours(template: NDArray) -> tuple[tuple[int, int], ...]:
    """Pairs (i < j) of which one is among the other's nearest names in the template."""
    d = np.linalg.norm(template[:, None] - template[None, :], axis=2)
    np.fill_diagonal(d, np.inf)
    k = min(TEMPLATE_NEIGHBOURS, max(len(template) - 1, 0))
    near = np.zeros(d.shape, dtype=bool)
    np.put_along_axis(near, np.argsort(d, axis=1)[:, :k], True, axis=1)
    near |= near.T
    return tuple((int(i), int(j)) for i, j in zip(*np.nonzero(np.triu(near, 1)), strict=True))


def _ahead(marker_set: MarkerSet) -> tuple[tuple[int, int], ...]:
    x = marker_set.template_mm[:, 0]
    index = {n: i for i, n in enumerate(marker_set.names)}
    out = []
    for a, b in marker_set.segments + marker_set.hinge_segments:
        i, j = index[a], index[b]
        if abs(x[i] - x[j]) > NEAR_FRACTION * marker_set.height_mm:
            out.append((i, j) if x[i] > x[j] else (j, i))
    return tuple(out)


@dataclass(frozen=True)
class AnatomyCheck:
    """Agreement of labelled trajectories with the anatomy.

    Attributes
    ----------
    confidence : (n,) array
        Per name, the smallest fraction of fields in which a check involving it holds
        (NaN where no check could be made: the name is not seen, or has no partner).
    forward : str
        Where the subject's forward direction came from: ``"walking"``, ``"pelvis"``,
        ``"feet"`` or ``"none"``.
    """

    confidence: NDArray[np.float64]
    forward: str


def _smooth(values: NDArray, sigma: float) -> NDArray:
    """Gaussian smoothing along axis 0 that ignores NaN (normalised convolution)."""
    ok = np.isfinite(values)
    num = gaussian_filter1d(np.where(ok, values, 0.0), sigma, axis=0, mode="nearest")
    den = gaussian_filter1d(ok.astype(float), sigma, axis=0, mode="nearest")
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0.2, num / den, np.nan)


def _mean_of(pos: NDArray, rows: tuple[int, ...]) -> NDArray:
    if not rows:
        return np.full(pos.shape[1:], np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # fields where none is seen
        return np.nanmean(pos[list(rows)], axis=0)


def _pelvis_facing(pos: NDArray, anatomy: Anatomy) -> NDArray[np.float64]:
    """The pelvis' horizontal back-to-front direction per field (F, 2), unit (NaN where
    its front or back markers are not seen, or the set has none)."""
    gap = (_mean_of(pos, anatomy.front) - _mean_of(pos, anatomy.back))[:, :2]
    norm = np.linalg.norm(gap, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(norm > 0, gap / norm, np.nan)


def forward_directions(
    pos: NDArray, anatomy: Anatomy, rate_hz: float
) -> tuple[NDArray[np.float64], str]:
    """The subject's horizontal forward direction per field (F, 2), unit, NaN where
    unknown, and what it came from.

    While walking (pelvis, or all names' centroid, faster than :data:`WALKING_MM_S`), the
    smoothed walking direction, unless the subject moves otherwise than forward
    (:data:`ALONG_FRACTION`: then the pelvis' back-to-front direction in each field);
    standing, the pelvis' back-to-front direction; else the feet's heel-to-toe direction.
    """
    sigma = max(DIRECTION_S * rate_hz, 1.0)
    centre = _mean_of(pos, anatomy.front + anatomy.back) if anatomy.front else None
    if centre is None or np.isnan(centre[:, 0]).all():
        centre = _mean_of(pos, tuple(range(pos.shape[0])))
    velocity = np.gradient(_smooth(centre[:, :2], sigma), axis=0) * rate_hz
    speed = np.linalg.norm(velocity, axis=1)
    walking = speed > WALKING_MM_S
    if walking.mean() > 0.5:
        with np.errstate(invalid="ignore"):
            travel = np.where(walking[:, None], velocity / speed[:, None], np.nan)
        facing = _pelvis_facing(pos, anatomy)
        with np.errstate(invalid="ignore"):
            along = np.sum(travel * facing, axis=1)
        agree = np.mean(along[np.isfinite(along)] > 0) if np.isfinite(along).any() else 1.0
        if 1 - ALONG_FRACTION < agree < ALONG_FRACTION:
            return facing, "pelvis"
        return travel, "walking"
    # Standing: the pelvis' back-to-front and the feet's heel-to-toe directions, which
    # must agree when both are known (else a front/back mix-up could turn every side).
    found = {} if feet_against_pelvis(pos, anatomy) else _standing_facing(pos, anatomy)
    if found:
        source, d = next(iter(found.items()))
        return np.tile(d, (pos.shape[1], 1)), source
    return np.full((pos.shape[1], 2), np.nan), "none"


def _standing_facing(pos: NDArray, anatomy: Anatomy) -> dict[str, NDArray[np.float64]]:
    """The median horizontal back-to-front direction of the pelvis (``"pelvis"``) and
    heel-to-toe direction of the feet (``"feet"``), unit, of those the names give."""
    found = {}
    for source, (a, b) in (
        ("pelvis", (anatomy.back, anatomy.front)),
        ("feet", (anatomy.heel, anatomy.toe)),
    ):
        if a and b:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                d = np.nanmedian((_mean_of(pos, b) - _mean_of(pos, a))[:, :2], axis=0)
            if np.isfinite(d).all() and np.linalg.norm(d) > 0:
                found[source] = d / np.linalg.norm(d)
    return found


def feet_against_pelvis(pos: NDArray, anatomy: Anatomy) -> bool:
    """Whether the names' pelvis faces against their feet (:func:`_standing_facing`):
    part of the body is named turned round."""
    found = _standing_facing(pos, anatomy)
    return len(found) == 2 and float(found["pelvis"] @ found["feet"]) < 0


def _fraction(holds: NDArray, valid: NDArray) -> NDArray[np.float64]:
    """Fraction of the valid fields in which ``holds``, per row (NaN without one)."""
    n = valid.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, np.sum(holds & valid, axis=-1) / n, np.nan)


def _relations(pos: NDArray, anatomy: Anatomy, forward: NDArray, source: str, floor: float):
    """(names, fraction) of every check: the names each involves and how often it holds."""
    left = np.stack([-forward[:, 1], forward[:, 0]], axis=1)
    out = []
    if anatomy.pairs:
        a, b = np.array(anatomy.pairs).T
        across = np.sum((pos[a, :, :2] - pos[b, :, :2]) * left, axis=2)
        out.append((np.stack([a, b], axis=1), _fraction(across > 0, np.isfinite(across))))
    if source == "walking" and anatomy.front and anatomy.back:
        gap = _mean_of(pos, anatomy.front) - _mean_of(pos, anatomy.back)
        ahead = np.sum(gap[:, :2] * forward, axis=1)
        rows = np.array([anatomy.front + anatomy.back])
        out.append((rows, _fraction(ahead > 0, np.isfinite(ahead))[None]))
    if anatomy.above:
        a, b = np.array(anatomy.above).T
        dz = pos[a, :, 2] - pos[b, :, 2]
        out.append((np.stack([a, b], axis=1), _fraction(dz > 0, np.isfinite(dz))))
    if anatomy.ahead:
        a, b = np.array(anatomy.ahead).T
        dx = np.sum((pos[a, :, :2] - pos[b, :, :2]) * forward, axis=2)
        out.append((np.stack([a, b], axis=1), _fraction(dx > 0, np.isfinite(dx))))
    if anatomy.heights_mm is not None:
        rows = np.arange(pos.shape[0])[:, None]
        near, standing = _near_height(pos, anatomy, floor)
        out.append((rows, _fraction(near, np.isfinite(pos[..., 2]) & standing[None])))
    return out


def _confidence(
    pos: NDArray, anatomy: Anatomy, forward: NDArray, source: str, floor: float
) -> NDArray:
    conf = np.full(pos.shape[0], np.inf)
    for rows, fraction in _relations(pos, anatomy, forward, source, floor):
        value = np.repeat(np.where(np.isnan(fraction), np.inf, fraction), rows.shape[1])
        np.minimum.at(conf, rows.ravel(), value)
    conf[np.isinf(conf)] = np.nan
    return conf


def check_anatomy(pos: NDArray, anatomy: Anatomy, rate_hz: float) -> AnatomyCheck:
    """Per name, how often the labelled trajectories ``pos`` (n, F, 3; NaN where a name
    is not seen) agree with ``anatomy``: left names left of their right partners (across
    the subject's forward direction), anterior pelvis markers ahead of posterior ones
    while walking, upper markers above lower ones, front markers of a segment ahead of
    its back ones, every marker near its template height above the floor."""
    forward, source = forward_directions(pos, anatomy, rate_hz)
    return AnatomyCheck(
        _confidence(pos, anatomy, forward, source, floor_height(pos, anatomy)), source
    )


check_anatomy.__doc__ = (
    (check_anatomy.__doc__ or "")
    + """

    Examples
    --------
    >>> from kisscal.markersets import marker_set
    >>> from kisscal.synth.motion import walking_trial
    >>> m = walking_trial(1, 150, 50.0, path_mm=3500, model="grounded", heading_deg=300)
    >>> kiss = marker_set("kiss")
    >>> pos = m.xyz_mm.transpose(1, 0, 2)[[m.names.index(n) for n in kiss.names]]
    >>> check = check_anatomy(pos, Anatomy.of_set(kiss), 50.0)
    >>> check.forward, bool(check.confidence.min() > 0.85)
    ('walking', True)
    >>> swapped = pos[[kiss.names.index(n) for n in ("SACR", "LASI", "RASI")] + list(range(3, 15))]
    >>> bool(check_anatomy(swapped, Anatomy.of_set(kiss), 50.0).confidence[1] < 0.2)
    True
"""
)


def floor_height(pos: NDArray, anatomy: Anatomy) -> float:
    """Height of the floor: where the lowest marker spends its lowest tenth of the time,
    put at the lowest template height (feet markers sit a few centimetres above it); the
    same whatever the names."""
    if anatomy.heights_mm is None:
        return float("nan")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # names never seen
        lowest = np.nanmin(np.nanpercentile(pos[..., 2], 10, axis=1))
    return float(lowest - np.min(anatomy.heights_mm))


def _near_height(pos: NDArray, anatomy: Anatomy, floor: float) -> tuple[NDArray, NDArray]:
    """Per name and field, whether the marker is within the height tolerance of its
    template height above the floor; and per field, whether the body stands there.

    A body that squats, jumps or crouches leaves its template heights as a whole, which
    says nothing of a name: in a field where a quarter of the names sit over half the
    tolerance off (all of them the same way), the body does not stand, and no name is
    judged by its height there (:data:`STANDING_QUANTILE`). A walk's swing foot, or a
    foreign marker holding a name, moves too few names. (A synthetic squat's right
    pelvis names kept within the tolerance in 79 % of the fields, and were flagged.)"""
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # fields where no name is seen
        gap = pos[..., 2] - floor - anatomy.heights_mm[:, None]
        low, high = np.nanpercentile(gap, [STANDING_QUANTILE, 100 - STANDING_QUANTILE], axis=0)
        half = 0.5 * anatomy.height_tolerance_mm
        return np.abs(gap) < anatomy.height_tolerance_mm, ~((low < -half) | (high > half))


def settle_sides(
    pos: NDArray, anatomy: Anatomy, rate_hz: float, min_confidence: float
) -> tuple[NDArray[np.int64], list[tuple[int, int]]]:
    """Name rows after exchanging the names of pairs the anatomy finds the wrong way round
    in more than ``min_confidence`` of the fields (the permutation, and the pairs).

    Left/right pairs first (a name left of its right partner); then pairs of one side or
    one segment (above, ahead: an ankle and a heel swapped), each exchanged only if that
    makes both names agree with the anatomy and the two are template neighbours
    (``anatomy.neighbours``): the labelling confuses neighbours; an elbow's name below
    the pelvis' back marker on one side means a foreign marker (a forearm's) holds the
    elbow's name, and giving it the pelvis' name would make two names wrong.
    ``pos[i]`` is the trajectory named ``anatomy.names[i]``; the result ``perm`` says
    that trajectory ``i`` is name ``perm[i]``.
    """
    forward, source = forward_directions(pos, anatomy, rate_hz)
    left = np.stack([-forward[:, 1], forward[:, 0]], axis=1)
    perm = np.arange(pos.shape[0])
    done = []
    for a, b in anatomy.pairs:
        across = np.sum((pos[a, :, :2] - pos[b, :, :2]) * left, axis=1)
        right_way = _fraction(across > 0, np.isfinite(across))
        if right_way < 1.0 - min_confidence:
            perm[[a, b]] = perm[[b, a]]
            done.append((a, b))
    for a, b in lone_wrong_side(
        pos, anatomy.pairs, anatomy.front + anatomy.back, left, min_confidence
    ):
        perm[[a, b]] = perm[[b, a]]
        done.append((a, b))
    moved = np.empty_like(pos)
    moved[perm] = pos
    if source == "walking":
        # An ASIS and the sacrum exchanged pass every left/right check (pelvis.py).
        for a, b in settle_pelvis(moved, anatomy.front, anatomy.back, forward, min_confidence):
            moved[[a, b]] = moved[[b, a]]
            at_a, at_b = np.flatnonzero(perm == a)[0], np.flatnonzero(perm == b)[0]
            perm[at_a], perm[at_b] = b, a
            done.append((a, b))
    floor = floor_height(pos, anatomy)
    conf = _confidence(moved, anatomy, forward, source, floor)
    close = None if anatomy.neighbours is None else set(anatomy.neighbours)
    for a, b in anatomy.above + anatomy.ahead:
        if close is not None and (min(a, b), max(a, b)) not in close:
            continue
        if not (conf[a] < 1.0 - min_confidence and conf[b] < 1.0 - min_confidence):
            continue
        trial = moved.copy()
        trial[[a, b]] = moved[[b, a]]
        trial_conf = _confidence(trial, anatomy, forward, source, floor)
        if min(trial_conf[a], trial_conf[b]) >= min_confidence:
            moved, conf = trial, trial_conf
            at_a, at_b = np.flatnonzero(perm == a)[0], np.flatnonzero(perm == b)[0]
            perm[at_a], perm[at_b] = b, a
            done.append((a, b))
    return perm, done
