"""Whether another name fits a trajectory clearly better than its own.

The anatomy (:mod:`~kisscal.tracking.labelling.anatomy`) checks relations that a wrong
name can satisfy as well as the right one: a leg whose names moved up by one (the thigh's
name on the knee marker, the knee's on a foreign marker below it) still has every upper
name above its lower one and near its template height within the anatomy's tolerance.
And the subject's template, fitted to the names the labelling gave
(:func:`~kisscal.tracking.labelling.subject.fit_template`), confirms whatever it was
fitted to. So each name is also weighed against every other name of the set on evidence
the labelling did not shape (:func:`name_margins`): the trajectory's median distances to
its named neighbours and its height above the floor, against the set's own template
(scaled to the subject; what scale remains between the two is measured over all named
neighbours and taken out). A name that another name fits by more than
``name_deficit_fraction`` of stature better is flagged.

On real files, against a generic template, right names fall short of their runner-up
by up to about 20 mm (marker placement differs from the template's); so the margin
cannot certify a name (most names would have to be flagged), it can only catch a name
that the evidence clearly contradicts. A name left free by the labelling is another
matter (:func:`name_margins` ``among_free``): nothing else claims it, so a trajectory
it fits better than the trajectory's own name is doubtful by a smaller margin
(``free_deficit_fraction``), and by any margin when none of its nearest names in the
template is held while the free name's are (:func:`strays`: a finger's name on a thigh
marker with the whole arm free). A name held by a doubted trajectory is as good as free
(:func:`chained`: a chain of names shifted along a limb holds every name). And the two
legs stand level (:func:`uneven_legs`).
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.state import RIGID_SPREAD_MM, median_distances

#: Neighbours: named trajectories whose median distance is below this fraction of the
#: template's height (a foot's names weighed by the shank and foot, not the head).
NEIGHBOUR_FRACTION = 0.35
#: Fields sampled (evenly) for the median distances.
MARGIN_FIELDS = 200
#: Left and right leg markers whose median heights differ by more than this fraction of
#: stature are doubtful (:func:`uneven_legs`). On the regression set (issue 26), true leg
#: names differ by up to 8.0 % (the tennis serve's thighs: one knee bent through the
#: serve); a leg whose names moved by one marker, by 12-16 % (test1.c3d, standing).
UNEVEN_FRACTION = 0.10
#: A name's template neighbours (:func:`isolated`): its this many nearest names in the
#: template (a finger's: the wrist bar's two ends and the forearm; a heel's: the ankle,
#: the toe and the tibia).
TEMPLATE_NEIGHBOURS = 3
#: An unnamed trajectory stands in for a free name of a rigid pair when its distance to
#: the held one is within this fraction of the template's (:func:`turned_round`; on the
#: regression set a real head is 30 % longer than the set's template, scaled).
TURNED_MATCH = 0.5


def name_margins(
    pos: NDArray,
    template: NDArray,
    heights_mm: NDArray | None,
    floor_mm: float,
    pairs: tuple[tuple[int, int], ...] = (),
    among_free: bool = False,
    weighed: NDArray | None = None,
) -> NDArray[np.float64]:
    """Per name (rows of ``pos``, (n, F, 3), Z up), the margin (mm) of its trajectory's
    fit to its own name over its fit to the best other name (NaN: not seen, or no
    neighbour, or no other name to weigh).

    The fit of trajectory ``i`` to name ``j`` is the median, over its neighbours ``k``
    (:data:`NEIGHBOUR_FRACTION` of the template's height) and the floor, of the absolute
    difference between the measured median distance ``i``-``k`` (height above
    ``floor_mm``), divided by the trial's scale to the template, and the template's
    distance between ``j`` and ``k``'s name (``j``'s height in ``heights_mm``; without
    them, or without a floor, distances alone); when ``j`` is ``k``'s name, the two
    exchange, and ``k`` is weighed as ``i``'s name. A name's mirror partner (``pairs``:
    left, right) is no runner-up: distances cannot tell a body from its mirror image,
    the anatomy's sides do. With ``among_free``, the other names weighed are only those
    no trajectory holds; ``weighed`` ((n, n) bool), only the
    names ``j`` with ``weighed[i, j]`` for trajectory ``i``.
    """
    n = pos.shape[0]
    fits = name_fits(pos, template, heights_mm, floor_mm)
    mirror = mirror_rows(n, pairs)
    held = np.isfinite(pos[..., 0]).any(axis=1)
    margins = np.full(n, np.nan)
    for i in np.flatnonzero(np.isfinite(fits).any(axis=1)):
        other = np.ones(n, dtype=bool)
        other[[i, mirror[i]]] = False
        if among_free:
            other &= ~held
        if weighed is not None:
            other &= weighed[i]
        if other.any():
            margins[i] = float(fits[i, other].min() - fits[i, i])
    return margins


def mirror_rows(n: int, pairs: tuple[tuple[int, int], ...]) -> NDArray[np.int64]:
    """Each name's mirror partner's row (its own row without one)."""
    mirror = np.arange(n)
    for a, b in pairs:
        mirror[a], mirror[b] = b, a
    return mirror


def name_fits(
    pos: NDArray, template: NDArray, heights_mm: NDArray | None, floor_mm: float
) -> NDArray[np.float64]:
    """(n, n) fit (mm) of the trajectory named ``i`` to the name ``j`` (NaN: not seen,
    or no neighbour), as :func:`name_margins` weighs it: the median misfit of its
    distances to its neighbours and of its height."""
    n = pos.shape[0]
    fits = np.full((n, n), np.nan)
    seen = np.flatnonzero(np.isfinite(pos[..., 0]).any(axis=0))  # at most MARGIN_FIELDS
    seen = seen[np.linspace(0, seen.size - 1, min(MARGIN_FIELDS, seen.size)).astype(int)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # pairs never seen together
        measured = median_distances(pos, np.arange(n), seen)
    tdist = np.linalg.norm(template[:, None] - template[None, :], axis=2)
    near = np.isfinite(measured) & (measured < NEIGHBOUR_FRACTION * float(np.ptp(template[:, 2])))
    np.fill_diagonal(near, False)
    if not near.any():
        return fits
    scale = float(np.median(measured[near] / np.maximum(tdist[near], 1.0)))
    measured = measured / scale
    known = heights_mm is not None and np.isfinite(floor_mm)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # names never seen
        height = (np.nanmedian(pos[..., 2], axis=1) - (floor_mm if known else 0.0)) / scale
    rows = np.arange(n)[:, None]
    for i in np.flatnonzero(near.any(axis=1) & np.isfinite(height)):
        k = np.flatnonzero(near[i])
        # (candidate name j, neighbour k): the template distance of j to k's name, k's
        # name being i when k is named j (an exchange).
        partner = np.where(k[None, :] == rows, i, k[None, :])
        misfit = np.abs(measured[i, k][None, :] - tdist[rows, partner])
        if known:
            misfit = np.c_[misfit, np.abs(height[i] - heights_mm)]
        fits[i] = np.median(misfit, axis=1)
    return fits


def chained(
    fits: NDArray, mirror: NDArray, doubtful: NDArray, margin_mm: float
) -> NDArray[np.bool_]:
    """``doubtful`` (per name) spread along links of names shifted one marker.

    ``fits`` from :func:`name_fits` (rows: trajectories by their names; NaN: not held).
    A trajectory whose own name another held name beats by more than ``margin_mm`` (a
    mirror partner excepted) is displaced; a displaced trajectory that prefers the name
    of another displaced one is a link of a shifted chain. A link to a doubtful holder
    makes the trajectory doubtful (that name is as good as free), and a doubtful
    trajectory's best link makes the holder doubtful (if the one is that name's marker,
    the other is not). Repeated until nothing changes.

    A chain of names shifted one marker along a limb (test1.c3d, standing: the
    sternum's name on the elbow, the elbow's on the forearm, ..., the finger's on the
    thigh, the thigh's on the knee, ..., the ankle's on the other foot's toe) holds every
    name, so no name is free to compare with, and each link fits its neighbour's name
    better by less than ``name_deficit_fraction``; but the links where the shift is
    plain (the anatomy's order of the knee and the shank) are doubted, and the shift
    carries the doubt along the chain to both its ends. A true name beaten by a doubted
    neighbour's (a toe by its ankle's) is no link when that neighbour's own name is not
    beaten: on the regression set such one-sided preferences flagged 4 right names.
    """
    n = fits.shape[0]
    gain = np.diagonal(fits)[:, None] - fits
    held = np.isfinite(np.diagonal(fits))
    other = np.isfinite(gain) & held[None, :] & ~np.eye(n, dtype=bool)
    other[np.arange(n), mirror] = False
    with np.errstate(invalid="ignore"):
        better = other & (gain > margin_mm)
    link = better & better.any(axis=1)[None, :]
    best = np.argmax(np.where(link, gain, -np.inf), axis=1)
    linked = link.any(axis=1)
    out = doubtful.copy()
    while True:
        grown = out | (link & out[None, :]).any(axis=1)
        grown[best[out & linked]] = True
        if np.array_equal(grown, out):
            return out
        out = grown


def nearest_names(template: NDArray) -> NDArray[np.int64]:
    """(n, k) each name's :data:`TEMPLATE_NEIGHBOURS` nearest names in the template."""
    d = np.linalg.norm(template[:, None] - template[None, :], axis=2)
    np.fill_diagonal(d, np.inf)
    k = min(TEMPLATE_NEIGHBOURS, max(len(template) - 1, 0))
    return np.argsort(d, axis=1)[:, :k]


def isolated(pos: NDArray, template: NDArray) -> NDArray[np.bool_]:
    """Per name (rows of ``pos``, (n, F, 3)), whether it is held while none of its
    :data:`TEMPLATE_NEIGHBOURS` nearest names in ``template`` is."""
    held = np.isfinite(pos[..., 0]).any(axis=1)
    return held & ~held[nearest_names(template)].any(axis=1)


def strays(
    pos: NDArray,
    template: NDArray,
    heights_mm: NDArray | None,
    floor_mm: float,
    pairs: tuple[tuple[int, int], ...] = (),
) -> NDArray[np.bool_]:
    """Per name, whether it is :func:`isolated` and a free name that has a held template
    neighbour (other than the name itself) fits its trajectory better by any margin.

    A marker set is placed in groups (a head, a hand, a foot), and a trial records whole
    groups or leaves them out: a name held alone among its group's free names, whose
    trajectory a free name of a held group fits better, is a name the labelling pushed
    along the body onto a marker of that group (a thigh marker named finger in a trial
    without arms, the thigh's name free, the knee's held). Its distances may fit the free
    name better by only a few millimetres (the free names' margins), which a true
    name's can too, but a true name alone (a shoulder without the trunk's markers) is
    beaten by names of groups that are absent as well.
    """
    held = np.isfinite(pos[..., 0]).any(axis=1)
    alone = isolated(pos, template)
    if not alone.any():
        return alone
    nearest = nearest_names(template)
    rows = np.arange(len(held))[:, None, None]
    # anchored[i, j]: j is free and one of its nearest names other than i is held.
    anchored = ~held[None, :] & (held[nearest][None] & (nearest[None] != rows)).any(axis=2)
    margins = name_margins(pos, template, heights_mm, floor_mm, pairs, weighed=anchored)
    with np.errstate(invalid="ignore"):
        return alone & (margins < 0)


def turned_round(
    pos: NDArray,
    spare: NDArray,
    ahead: tuple[tuple[int, int], ...],
    template: NDArray,
    forward: NDArray,
    min_fraction: float,
    spare_names: NDArray | None = None,
) -> NDArray[np.bool_]:
    """Per name, whether it holds one end of a front/back pair of one segment
    (``ahead``: front, back) whose other name is free, while an unnamed trajectory of
    ``spare`` (m, F, 3) moves rigidly with it (distance SD below
    :data:`~kisscal.tracking.labelling.state.RIGID_SPREAD_MM`, median within
    :data:`TURNED_MATCH` of the pair's template distance) on the other side than the
    free name's: ahead of a back name held alone, behind a front one, along ``forward``
    (F, 2) in ``min_fraction`` of the fields.

    The anatomy's front/back check needs both names held; a segment whose front names
    went to its back markers (a head whose back markers were matched to the forehead's
    names, the forehead's left unnamed) holds no back name to check against. Its
    unnamed front markers still say which way round it is. A spare that holds a name
    (``spare_names``: its row, -1 unnamed; a doubted name) counts only when the pair
    turned round explains its place better than its own name
    (:func:`_explained_by_name`).
    """
    out = np.zeros(pos.shape[0], dtype=bool)
    held = np.isfinite(pos[..., 0]).any(axis=1)
    if not spare.shape[0]:
        return out
    names = np.full(spare.shape[0], -1) if spare_names is None else np.asarray(spare_names)
    for front, back in ahead:
        for own, free, side in ((front, back, -1.0), (back, front, 1.0)):
            if not held[own] or held[free]:
                continue
            d = np.linalg.norm(spare - pos[own][None], axis=2)
            want = float(np.linalg.norm(template[front] - template[back]))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # never seen together
                rigid = (np.nanstd(d, axis=1) < RIGID_SPREAD_MM) & (
                    np.abs(np.nanmedian(d, axis=1) - want) < TURNED_MATCH * want
                )
            along = np.sum((spare[..., :2] - pos[own][None, :, :2]) * forward, axis=2)
            ok = np.isfinite(along)
            n = np.maximum(ok.sum(axis=1), 1)
            wrong = np.sum(ok & (side * along < 0), axis=1) >= min_fraction * n
            rigid &= ~_explained_by_name(spare, names, pos[own], own, free, template, forward)
            out[own] |= bool(np.any(rigid & wrong & (ok.sum(axis=1) > 0)))
    return out


def _explained_by_name(
    spare: NDArray,
    names: NDArray,
    own_pos: NDArray,
    own: int,
    free: int,
    template: NDArray,
    forward: NDArray,
) -> NDArray[np.bool_]:
    """Per spare, whether it holds a name whose template offset from ``own`` (along the
    walk and up: the template's x and z) fits its median offset from ``own_pos`` better
    than the pair turned round does (``own``'s marker being ``free``'s, the spare
    ``own``'s).

    A doubted toe beside its ankle, the heel free, sits ahead of the ankle as a turned
    heel would, but where its own name puts it (gait-pig-nz); a doubted head name on
    the true C7 marker sits behind C7's name on the clavicle where C7 would, 110 mm from
    where the head name would (Vicon_analysis without arms)."""
    out = np.zeros(spare.shape[0], dtype=bool)
    named = np.flatnonzero(names >= 0)
    if not named.size:
        return out
    gap = spare[named] - own_pos[None]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # never seen together
        seen = np.c_[
            np.nanmedian(np.sum(gap[..., :2] * forward, axis=2), axis=1),
            np.nanmedian(gap[..., 2], axis=1),
        ]
    turned = (template[own] - template[free])[[0, 2]]
    as_named = (template[names[named]] - template[own])[:, [0, 2]]
    own_fit = np.linalg.norm(seen - as_named, axis=1)
    out[named] = own_fit <= np.linalg.norm(seen - turned, axis=1)
    return out


def uneven_legs(
    pos: NDArray, heights_mm: NDArray, pairs: tuple[tuple[int, int], ...], pelvis: tuple[int, ...]
) -> NDArray[np.bool_]:
    """Per name, whether it is a leg's (template height below the pelvis' markers) whose
    trajectory's median height differs from its mirror partner's by more than
    :data:`UNEVEN_FRACTION` of the template's height (both names of such a pair).

    A walk, a run, a jump or a stance puts both legs' markers at one height on average;
    a leg whose names moved along it by one marker (the thigh's name on the knee, the
    knee's on the shin: each still above the next, each near enough its template height
    for the anatomy) does not stand level with the other leg. Which of the two moved is
    not known, so both are doubtful.
    """
    out = np.zeros(pos.shape[0], dtype=bool)
    if not pelvis or not pairs:
        return out
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # names never seen
        height = np.nanmedian(pos[..., 2], axis=1)
    legs = heights_mm < np.min(heights_mm[list(pelvis)])
    limit = UNEVEN_FRACTION * float(np.ptp(heights_mm))
    for a, b in pairs:
        if legs[a] and legs[b] and abs(height[a] - height[b]) > limit:
            out[[a, b]] = True
    return out
