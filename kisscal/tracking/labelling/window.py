"""Phase 1 (and 3): names for the long pieces seen through most of a window of fields.

Core: long pieces seen in most rich fields of the window. Their median pairwise
distances describe an average pose; classical MDS turns it into points (up to a rigid
motion and a mirror image) that are matched to the standing template, the correspondence
is improved by :func:`~kisscal.tracking.rigid.refine_by_swaps`, and of it and its mirror
image the one that fits the real fields with a proper rotation is kept. The median
averages out the swing of the legs, which a single field's rigid fit cannot.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.labelling.core import core_pieces, crowded, held_whole
from kisscal.tracking.labelling.facing import better, facing
from kisscal.tracking.labelling.pair_swaps import settle_rigid_swaps
from kisscal.tracking.labelling.state import (
    RIGID_MATCH_MM,
    RIGID_SPREAD_MM,
    LabelState,
    distance_spread,
    median_distances,
    rich_fields,
)
from kisscal.tracking.labelling.upright import (
    average_pose,
    capped_assignment,
    height_costs,
    pose_on_template,
)
from kisscal.tracking.rigid import (
    classical_mds,
    field_fits,
    kabsch,
    leave_savings,
    refine_by_swaps,
    refine_with_kicks,
    rigid_matches,
    swap_cost,
    upright_fraction,
    upright_pose,
)

# Floor (mm) of the spread of a pair's distance in the swap search weights: about the
# noise of a distance between two measured markers.
SPREAD_FLOOR_MM = 3.0
# Fields of a window the upright match turns onto the template (evenly spread).
UPRIGHT_FIELDS = 20
# Rigid matches of the average pose (per mirror image) from which the swap search starts.
SWAP_STARTS = 24
# Correspondences whose swap cost is within this factor of the lowest are near ties that
# the rigid fit to the real fields decides (a body and its mirror image, an ASIS and the
# sacrum when the pelvis' other markers are out of view).
NEAR_TIE = 1.05
# Price of a core piece left unnamed by the swap search, in median shares of the cost of
# its best naming (:func:`swap_refined`).
LEAVE_PRICE = 8.0


@dataclass(frozen=True)
class WindowMatch:
    """Names of a window's core pieces.

    Attributes
    ----------
    core : int array or None
        Rows of ``LabelState.dense`` matched (None when the window holds no body).
    assign : int array
        Name index per core row, -1 where left unnamed.
    fit_rms : float
        Median over the window's fields of the rigid fit RMS to the template (mm).
    rich : int array
        The window's fields used.
    """

    core: NDArray[np.int64] | None
    assign: NDArray[np.int64]
    fit_rms: float
    rich: NDArray[np.int64]


def window_fields(present: NDArray, centre: int, window: int, label_fields: int) -> NDArray:
    """Rich fields (see :func:`rich_fields`) of the window around ``centre``, at most
    ``label_fields`` of them, evenly spread."""
    n_fields = present.shape[1]
    in_window = np.zeros(n_fields, dtype=bool)
    lo = min(max(centre - window // 2, 0), max(n_fields - window, 0))
    in_window[lo : lo + window] = True
    rich = rich_fields(present & in_window[None, :])
    if rich.size > label_fields:
        rich = rich[np.linspace(0, rich.size - 1, label_fields).round().astype(int)]
    return rich


def swap_refined(
    median: NDArray,
    weight: NDArray,
    template: NDArray,
    template_distance: NDArray,
    tolerance_mm: float,
    heights: NDArray | None = None,
    unary: NDArray | None = None,
    leave: bool = False,
) -> tuple[list[tuple[float, NDArray[np.int64]]], float | None]:
    """(cost, names) from every rigid match of the average pose and of its mirror image,
    each improved by the swap search; and the price of a piece left unnamed (None
    without ``leave``).

    With ``heights`` (the core pieces' median heights, template Z up), the average pose
    is stood up first (:func:`~kisscal.tracking.rigid.upright_pose`) and matches that
    turn it over are not used as starts; ``unary`` (core pieces x names) adds each
    piece's own cost of a name to the swap search.

    With ``leave``, the best naming is searched again where a piece may be left unnamed
    at :data:`LEAVE_PRICE` times the median piece's share of its cost: a marker of no
    name of the set (a fifth metatarsal) then need not shift a chain of names to take
    one, while a piece that fits no worse than most pieces of the body keeps its name.
    The costs returned include the price.
    """
    embedded = classical_mds(median)
    if heights is not None:
        embedded = upright_pose(embedded, heights)
    n_names = template.shape[0]
    refined, ends = [], []
    for mirror in (1.0, -1.0):
        # Several rigid matches of the average pose serve as starts: the swap search
        # only descends, and one start can sit in a wrong valley.
        pose = (
            embedded * [1.0, mirror, 1.0] if heights is not None else embedded * [1.0, 1.0, mirror]
        )
        starts = rigid_matches(pose, template, tolerance_mm)
        for assign, _ in starts[:SWAP_STARTS]:
            if (assign >= 0).sum() < 3:
                continue
            if heights is not None and not _kept_upright(pose, template, assign):
                continue
            # Tracks too far from any name in the average pose still get a free name to
            # start from; the swap search then places them by their rigid partners.
            free = np.setdiff1d(np.arange(n_names), assign[assign >= 0])
            loose = np.flatnonzero(assign < 0)[: free.size]
            assign[loose] = free[: loose.size]
            assign = refine_by_swaps(median, weight, template_distance, assign, unary=unary)
            cost = swap_cost(assign, median, weight, template_distance, unary)
            refined.append((cost, assign))
        ends.append(len(refined))
    if refined:  # the best start, kicked out of its valley (cheaper than kicking every start)
        best = refine_with_kicks(
            median, weight, template_distance, min(refined, key=lambda c: c[0])[1], unary
        )
        refined.append((swap_cost(best, median, weight, template_distance, unary), best))
    if not (refined and leave):
        return refined, None
    # A piece's share: what leaving it out of the best naming saves.
    args = (median, weight, template_distance, unary)
    price = LEAVE_PRICE * float(np.median(leave_savings(best, *args)[best >= 0]))
    out = [a for _, a in refined]
    for side in (refined[: ends[0]], refined[ends[0] : ends[1]]):  # each mirror image's best
        if side:
            start = min(side, key=lambda c: c[0])[1]
            out.append(refine_with_kicks(median, weight, template_distance, start, unary, price))
    return [(swap_cost(a, *args, price), a) for a in out], price


def _kept_upright(pose: NDArray, template: NDArray, assign: NDArray) -> bool:
    ok = assign >= 0
    r, _ = kabsch(pose[ok], template[assign[ok]])
    return bool(r[2, 2] > np.cos(np.pi / 4))


def near_ties(
    refined: list,
    median: NDArray,
    weight: NDArray,
    template_distance: NDArray,
    unary: NDArray | None = None,
    price: float | None = None,
) -> list[tuple[float, NDArray[np.int64]]]:
    """``refined`` plus the neighbours of its best correspondences (one piece moved to a
    free name, or two pieces' names exchanged) whose swap cost is within
    :data:`NEAR_TIE` of the lowest.

    The swap search stops in one of two valleys that the averaged pose cannot tell
    apart (an ASIS or the sacrum seen without the rest of the pelvis); the rigid fit to
    the real fields then chooses between them (:func:`left_right_fits`).
    """
    lowest = min(c for c, _ in refined)
    bound = lowest * NEAR_TIE + 1e-9
    out = list(refined)
    seen_keys = {tuple(a) for _, a in refined}
    for cost, assign in refined:
        if cost > bound:
            continue
        named = np.flatnonzero(assign >= 0)
        free = np.setdiff1d(np.arange(template_distance.shape[0]), assign[named])
        variants = []
        for i in named:
            for x in free:
                variants.append(assign.copy())
                variants[-1][i] = x
        for i, k in itertools.combinations(named, 2):
            variants.append(assign.copy())
            variants[-1][[i, k]] = assign[[k, i]]
        for v in variants:
            if tuple(v) in seen_keys:
                continue
            seen_keys.add(tuple(v))
            c = swap_cost(v, median, weight, template_distance, unary, price)
            if c <= bound:
                out.append((c, v))
    return out


def left_right_fits(
    state: LabelState, refined: list, core: NDArray, rich: NDArray
) -> list[tuple[float, NDArray[np.int64]]]:
    """(median fit RMS over ``rich``, names) of the distance-wise best correspondences
    and of their mirror images: distances cannot tell left from right, a proper rigid
    fit to the real fields can."""
    lowest = min(c for c, _ in refined)
    candidates = []
    seen_keys = set()
    for cost, assign in refined:
        # Only the distance-wise best (and equally good) correspondences go on.
        if cost > lowest * NEAR_TIE + 1e-9 or tuple(assign) in seen_keys:
            continue
        seen_keys.add(tuple(assign))
        tries = [assign]
        if state.mirror_of is not None:
            tries.append(np.where(assign >= 0, state.mirror_of[np.maximum(assign, 0)], -1))
        for cand in tries:
            ok = cand >= 0
            if (
                state.upright
                and upright_fraction(state.dense, rich, core[ok], cand[ok], state.template) < 0.5
            ):
                continue
            rms = field_fits(state.dense, rich, core[ok], cand[ok], state.template)
            candidates.append((float(np.median(rms)) if rms.size else np.inf, cand))
    return candidates


def drop_broken_pairs(
    state: LabelState, assign: NDArray, median: NDArray, spread: NDArray
) -> NDArray[np.int64]:
    """Unname core pieces named as a given rigid pair that do not keep its distance.

    The averaged pose of a leg half out of view can shift names along it; spreading
    names the pieces later by their rigid partners.
    """
    named = np.flatnonzero(assign >= 0)
    pa, pb = np.meshgrid(named, named, indexing="ij")
    pair = state.given_rigid[assign[pa], assign[pb]]
    off = np.abs(median[pa, pb] - state.template_distance[assign[pa], assign[pb]])
    broken = pair & ((off > RIGID_MATCH_MM) | (spread[pa, pb] > RIGID_SPREAD_MM))
    assign = assign.copy()
    assign[named[broken.any(axis=1)]] = -1
    return assign


def set_members(
    state: LabelState, core: NDArray, rich: NDArray
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64] | None, bool]:
    """The core pieces that belong to the set, and the names they hold: in the average
    pose stood on the template (:func:`~kisscal.tracking.labelling.upright.pose_on_template`),
    the one-to-one assignment of pieces to names within ``label_tolerance_mm`` (all core
    pieces and names when it holds fewer than three names, or nearly all of them).

    A trial may hold only part of the set (a full-body set on a lower-body file) and
    markers of another set: the swap search then names only these pieces, among only
    these names, instead of forcing absent names on foreign pieces; so too when the
    names are all held but the core is :func:`crowded` with other pieces. Returned with the
    pieces' places in the stood pose (None with all pieces and names): with fewer names,
    distances alone tell less (a sternum from a back marker), the place tells more; and
    whether it stands on the lab's own floor (not on its lowest piece).
    """
    cap = state.params.label_tolerance_mm
    few = rich[np.linspace(0, rich.size - 1, min(UPRIGHT_FIELDS, rich.size)).astype(int)]
    pose, lab_floor = pose_on_template(state.dense[np.ix_(core, few)], state.template, cap)
    placed = np.flatnonzero(np.isfinite(pose[:, 0]))
    rows, cols, _ = capped_assignment(pose[placed], state.template, cap)
    if rows.size < 3 or (
        held_whole(rows.size, len(state.names)) and not crowded(core.size, len(state.names))
    ):
        # (nearly) the whole set and few others: the swap search sorts it out
        return core, np.arange(len(state.names)), None, lab_floor
    members = placed[rows]
    return core[members], np.sort(cols), pose[members], lab_floor


def match_window(state: LabelState, centre: int) -> WindowMatch:
    """Names for the long pieces seen through most of the window around ``centre``.

    With the session's segments (``state.given_rigid``), two core pieces named as a rigid
    pair must keep the template's distance; pieces that break it are left unnamed here.

    References
    ----------
    Torgerson 1952 (classical MDS); Kabsch 1976 (rigid fits).
    """
    params = state.params
    rich = window_fields(state.present, centre, state.window, params.label_fields)
    none = WindowMatch(None, np.empty(0, dtype=np.int64), float("nan"), rich)
    if rich.size == 0:  # never three tracks at once: no body to match
        return none
    core = core_pieces(state.present, rich, state.dense)
    if core.size < 3:
        return none
    names, pose, lab_floor = np.arange(len(state.names)), None, False
    if state.upright and state.partial:
        core, names, pose, lab_floor = set_members(state, core, rich)
    median = median_distances(state.dense, core, rich)
    spread = distance_spread(state.dense, core, rich)
    weight = 1.0 / (spread**2 + SPREAD_FLOOR_MM**2)
    np.fill_diagonal(weight, 0.0)
    heights = unary = None
    if state.upright:
        heights, unary = height_costs(state.dense, core, rich, state.template[names], lab_floor)
    if pose is not None:
        # Each piece's cost of a name: its distance from the name in the stood pose, in
        # label tolerances, squared.
        gap = np.linalg.norm(pose[:, None] - state.template[names][None], axis=2)
        unary = unary + (gap / params.label_tolerance_mm) ** 2
    refined, price = swap_refined(
        median,
        weight,
        state.template[names],
        state.template_distance[np.ix_(names, names)],
        params.label_tolerance_mm,
        heights,
        unary,
        leave=pose is None,
    )
    if not refined:
        return none
    tdist = state.template_distance[np.ix_(names, names)]
    refined = near_ties(refined, median, weight, tdist, unary, price)
    # Back to the set's name numbers.
    refined = [(cost, np.where(a >= 0, names[np.maximum(a, 0)], -1)) for cost, a in refined]
    candidates = left_right_fits(state, refined, core, rich)
    if not candidates:
        return none
    fit_rms, assign = min(candidates, key=lambda c: c[0])
    if state.given_rigid is not None:
        fit_rms, assign = settle_rigid_swaps(state, core, rich, assign, fit_rms)
        assign = drop_broken_pairs(state, assign, median, spread)
    return WindowMatch(core, assign, fit_rms, rich)


def first_centre(state: LabelState) -> int:
    """Centre of the window where most long pieces are seen."""
    box = np.ones(state.window)
    return int(np.argmax(np.convolve(state.present.sum(axis=0), box, mode="same")))


def first_pose(state: LabelState) -> tuple[NDArray, NDArray]:
    """The first window's core pieces (k, F, 3) over at most ``UPRIGHT_FIELDS`` fields,
    and their average pose (:func:`~kisscal.tracking.labelling.upright.average_pose`) at
    the lab's heights: a stature is judged by them.

    (:func:`set_members` keeps the fitted lift: at the lab's heights walking5 gave its
    LKNE and LTOE names to the knee centre and first metatarsal markers beside them.)"""
    rich = window_fields(state.present, first_centre(state), state.window, UPRIGHT_FIELDS)
    pos = state.dense[np.ix_(core_pieces(state.present, rich, state.dense), rich)]
    return pos, average_pose(pos, lift=False)


def shorter_windows(state: LabelState) -> list[tuple[int, int]]:
    """(centre, length) per window length, halving from ``label_window_fields`` down to
    twice ``label_fields``: the windows of that length holding most core pieces (long
    pieces seen whole, :func:`core_pieces`), when more than the longest window; of
    equals the latest first. (Every one: kiss 3 seed 361's latest of five named the body
    turned round, the four others facing forward and right.)"""
    params = state.params

    def n_core(centre: int, length: int) -> int:
        rich = window_fields(state.present, centre, length, params.label_fields)
        return core_pieces(state.present, rich, state.dense).size if rich.size else 0

    busiest = np.convolve(state.present.sum(axis=0), np.ones(state.window), mode="same")
    most = n_core(int(np.argmax(busiest)), state.window)
    out = []
    length = state.window // 2
    while length >= max(2 * params.label_fields, 3):
        centres = range(length // 2, state.n_fields - length // 2 + 1, max(length // 4, 1))
        counts = [(n_core(c, length), c) for c in centres]
        top = max(counts)[0] if counts else 0
        if top > most:
            out += [(c, length) for n, c in sorted(counts, reverse=True) if n == top]
        length //= 2
    return out


def _n_named(found: WindowMatch) -> int:
    return 0 if found.core is None else int(np.sum(found.assign >= 0))


def match_first_window(state: LabelState) -> bool:
    """Phase 1: name the core pieces of the window where most long pieces are seen.

    When that window names fewer than ``min_label_fraction`` of the names (with few
    cameras, gaps cut pieces, and a long window holds few of them whole), shorter windows
    holding more whole pieces (:func:`shorter_windows`) are matched too, longest first,
    as they are when it names a body turned round; one replaces the match kept so far
    as :func:`~kisscal.tracking.labelling.facing.better` decides (facing forward; then
    more names, agreeing with the kept ones). Later windows (phase 3) take its length.

    Sets ``state.rich`` and ``state.fit_rms``; False when no body was matched (the
    trial does not fit the marker set).
    """
    longest = state.window
    centre = first_centre(state)
    found, chosen = match_window(state, centre), longest
    few = _n_named(found) < state.params.min_label_fraction * len(state.names)
    turned = facing(state, found.core, found.assign, found.rich) <= 1 - state.params.facing_fraction
    if few or turned:
        for c, length in shorter_windows(state):
            state.window = length
            other = match_window(state, c)
            if better(state, found, other):
                found, centre, chosen = other, c, length
    state.window = chosen
    state.fit_rms, state.rich = found.fit_rms, found.rich
    if state.window < longest:
        # Rigid pairs are judged over the long window: over a short one, markers of two
        # segments can keep their distance by chance (a foot in stance, the pelvis).
        state.rich = window_fields(state.present, centre, longest, state.params.label_fields)
    if found.core is None or not np.any(found.assign >= 0):
        return False
    named = found.assign >= 0
    state.label_of[state.long_ids[found.core[named]]] = found.assign[named]
    for t in np.flatnonzero(state.label_of >= 0):
        state.name_piece(int(t), int(state.label_of[t]))
    return True
