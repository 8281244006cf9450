"""Automatic labelling of tracks with a marker set (beyond the seeds, which left it to the
operator).

With a template (marker positions in a standing pose, in any coordinate frame), a sample of
fields is matched to the template: at each field the points present are registered to the
template by a proper rigid motion with the correspondence found jointly (iterated
Hungarian assignment and Kabsch fit, started from the 24 axis-aligned orientations of the
two principal-axis frames), so neither where the subject stands nor where it faces
matters, and a mirrored (left/right swapped) match is impossible because reflections are
excluded. Each field votes a label for each track it contains; a track takes its majority
label when the votes and the fit distance support it. Pieces of one marker that share a
label and do not overlap in time are joined. Tracks that fit no label are reported and
named ``M<k>``; when too few names are matched (a stick, a thrown ball) all tracks are
named ``M1``, ``M2``, ... .
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import linear_sum_assignment

from kisscal.errors import KisscalError
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import Tracks, numbering


@dataclass(frozen=True)
class Labelling:
    """Result of :func:`label_tracks`.

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
    """

    tracks: Tracks
    labels: tuple[str, ...]
    fits_marker_set: bool
    unlabelled: tuple[int, ...]
    missing: tuple[str, ...]
    fit_rms_mm: float


def _cube_rotations() -> NDArray[np.float64]:
    """The 24 proper rotations that map coordinate axes onto coordinate axes."""
    mats = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            m[np.arange(3), perm] = signs
            if np.linalg.det(m) > 0:
                mats.append(m)
    return np.array(mats)


_CUBE = _cube_rotations()
# Floor (mm) of the spread of a pair's distance in the swap search weights: about the
# noise of a distance between two measured markers.
_SPREAD_FLOOR_MM = 3.0


def _principal_frame(points: NDArray) -> NDArray[np.float64]:
    _, vecs = np.linalg.eigh(np.cov(points.T))
    if np.linalg.det(vecs) < 0:
        vecs[:, 0] = -vecs[:, 0]
    return vecs


def kabsch(source: NDArray, target: NDArray) -> tuple[NDArray, NDArray]:
    """Proper rotation R and translation t minimising sum |R s + t - g|² (no reflection)."""
    cs, ct = source.mean(axis=0), target.mean(axis=0)
    h = (source - cs).T @ (target - ct)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return r, ct - r @ cs


def match_to_template(
    points: NDArray, template: NDArray, outlier_mm: float, iterations: int = 10
) -> tuple[NDArray[np.int64], float]:
    """Correspondence of ``points`` (k, 3) to ``template`` (n, 3) under a rigid motion.

    Returns the template index per point (-1 when unmatched or farther than
    ``outlier_mm`` after the fit) and the RMS distance of the matched points (mm).
    """
    k = points.shape[0]
    best = (np.full(k, -1, dtype=np.int64), np.inf, -1)
    if k < 3:
        return best[0], best[1]
    cp, ctm = points.mean(axis=0), template.mean(axis=0)
    fp, ft = _principal_frame(points), _principal_frame(template)
    cap = outlier_mm**2
    for g in _CUBE:
        r = ft @ g @ fp.T
        t = ctm - r @ cp
        prev = None
        for _ in range(iterations):
            moved = points @ r.T + t
            d2 = ((moved[:, None, :] - template[None, :, :]) ** 2).sum(axis=2)
            rows, cols = linear_sum_assignment(np.minimum(d2, cap))
            good = d2[rows, cols] < cap
            if good.sum() < 3:
                break
            key = tuple(cols[good]) + tuple(rows[good])
            if key == prev:
                break
            prev = key
            r, t = kabsch(points[rows[good]], template[cols[good]])
        moved = points @ r.T + t
        d2 = ((moved[:, None, :] - template[None, :, :]) ** 2).sum(axis=2)
        rows, cols = linear_sum_assignment(np.minimum(d2, cap))
        trimmed = np.minimum(d2[rows, cols], cap)
        # Unmatched points cost as much as an outlier, so larger matches are preferred.
        score = trimmed.sum() + cap * (k - rows.size)
        if score < best[1] * 1.0 - 1e-9 or best[2] < 0:
            assign = np.full(k, -1, dtype=np.int64)
            ok = d2[rows, cols] < cap
            assign[rows[ok]] = cols[ok]
            rms = float(np.sqrt(d2[rows[ok], cols[ok]].mean())) if ok.any() else np.inf
            best = (assign, score, rms)
    return best[0], float(best[2])


def _rich_fields(present: NDArray) -> NDArray[np.int64]:
    """Fields where at least 80 % of the largest number of simultaneous tracks are seen."""
    count = present.sum(axis=0)
    return np.flatnonzero(count >= max(3, 0.8 * count.max()))


def _median_distances(dense: NDArray, tracks: NDArray, fields: NDArray) -> NDArray:
    """Median over ``fields`` of the distance between every pair of ``tracks`` (NaN-aware)."""
    pts = dense[np.ix_(tracks, fields)]  # (k, F, 3)
    d = np.linalg.norm(pts[:, None] - pts[None, :], axis=3)  # (k, k, F)
    return np.nanmedian(d, axis=2)


def classical_mds(distance: NDArray, dims: int = 3) -> NDArray[np.float64]:
    """Points whose pairwise distances best match ``distance`` (Torgerson's classical MDS),
    up to a rigid motion and a reflection."""
    k = distance.shape[0]
    j = np.eye(k) - 1.0 / k
    b = -0.5 * j @ (distance**2) @ j
    vals, vecs = np.linalg.eigh(b)
    top = np.argsort(vals)[::-1][:dims]
    return vecs[:, top] * np.sqrt(np.maximum(vals[top], 0.0))


def _distance_spread(dense: NDArray, tracks: NDArray, fields: NDArray) -> NDArray:
    """Standard deviation over ``fields`` of the distance between every pair of tracks."""
    pts = dense[np.ix_(tracks, fields)]
    d = np.linalg.norm(pts[:, None] - pts[None, :], axis=3)
    return np.nanstd(d, axis=2)


def refine_by_swaps(
    distance: NDArray,
    weight: NDArray,
    template_distance: NDArray,
    assign: NDArray,
    max_passes: int = 20,
) -> NDArray[np.int64]:
    """Improve a track -> template assignment by exchanging labels (2-opt local search).

    Minimises ``sum_ij weight_ij (distance_ij - template_distance[a_i, a_j])²``: pairs of
    tracks whose distance barely varies (markers on one segment) weigh most, so the foot
    and shank markers, whose arrangement an average pose blurs, are put right. Tracks with
    ``assign < 0`` are left out; a track may also move to a name no track holds.
    """
    assign = assign.copy()
    rows = np.flatnonzero(assign >= 0)
    if rows.size < 3:
        return assign
    d = np.nan_to_num(distance[np.ix_(rows, rows)])
    w = np.nan_to_num(weight[np.ix_(rows, rows)])
    p = assign[rows]
    n_names = template_distance.shape[0]

    def cost(q: NDArray) -> float:
        return float((w * (d - template_distance[np.ix_(q, q)]) ** 2).sum())

    best = cost(p)
    for _ in range(max_passes):
        # Steepest descent: take the best single exchange of the pass, so that one very
        # wrong pair is fixed before the search wanders off after small gains.
        step = (best, None)
        for a in range(p.size):
            for b in range(a + 1, p.size):
                q = p.copy()
                q[a], q[b] = p[b], p[a]
                c = cost(q)
                if c < step[0] - 1e-9:
                    step = (c, q)
            for j in np.setdiff1d(np.arange(n_names), p):
                q = p.copy()
                q[a] = j
                c = cost(q)
                if c < step[0] - 1e-9:
                    step = (c, q)
        if step[1] is None:
            break
        best, p = step
    assign[rows] = p
    return assign


def _field_fits(
    dense: NDArray, fields: NDArray, rows: NDArray, cols: NDArray, template: NDArray
) -> NDArray[np.float64]:
    """RMS distance per field of a proper rigid fit of tracks ``rows`` to template ``cols``."""
    out = []
    for f in fields:
        ok = np.isfinite(dense[rows, f, 0])
        if ok.sum() < 3:
            continue
        src = dense[rows[ok], f]
        dst = template[cols[ok]]
        r, t = kabsch(src, dst)
        out.append(np.sqrt(np.mean(np.sum((src @ r.T + t - dst) ** 2, axis=1))))
    return np.asarray(out)


def label_tracks(
    tracks: Tracks,
    names: tuple[str, ...] | list[str] | None,
    params: TrackingParams,
    template_mm: ArrayLike | None = None,
) -> Labelling:
    """Name tracks from the marker set (DESIGN.md ``[markers]``).

    Parameters
    ----------
    tracks : Tracks
        Cleaned, blended tracks.
    names : sequence of str or None
        Marker names. Without names or without a template, tracks are named M1, M2, ...
    params : TrackingParams
        ``label_tolerance_mm``, ``label_fields``, ``min_label_fraction``.
    template_mm : (n, 3) array, optional
        Marker positions in a standing pose, same order as ``names``, any frame.

    Returns
    -------
    Labelling
    """
    n_tracks = tracks.n_tracks
    generic = tuple(f"M{i + 1}" for i in range(n_tracks))
    if not names or template_mm is None or n_tracks == 0:
        return Labelling(tracks, generic, False, (), tuple(names or ()), float("nan"))
    names = tuple(names)
    template = np.asarray(template_mm, dtype=float)
    if template.shape != (len(names), 3):
        raise KisscalError(
            f"markers: template_mm needs one [x, y, z] per name ({len(names)}), "
            f"got shape {template.shape}"
        )
    if len(set(names)) != len(names):
        raise KisscalError("markers: names must be unique")
    dense = tracks.positions()
    present = np.isfinite(dense[..., 0])
    rich = _rich_fields(present)
    if rich.size == 0:  # never three tracks at once: no body to match
        return Labelling(tracks, generic, False, (), names, float("nan"))
    if rich.size > params.label_fields:
        rich = rich[np.linspace(0, rich.size - 1, params.label_fields).round().astype(int)]
    # Core: tracks seen in most rich fields. Their median pairwise distances over the
    # trial describe an average pose; classical MDS turns it into points (up to a rigid
    # motion and a mirror image) that are matched to the standing template. The median
    # averages out the swing of the legs, which a single field's rigid fit cannot.
    core = np.flatnonzero(present[:, rich].mean(axis=1) >= 0.5)
    label_of = np.full(n_tracks, -1, dtype=np.int64)
    fit_rms = float("nan")
    if core.size >= 3:
        median = _median_distances(dense, core, rich)
        weight = 1.0 / (_distance_spread(dense, core, rich) ** 2 + _SPREAD_FLOOR_MM**2)
        np.fill_diagonal(weight, 0.0)
        template_distance = np.linalg.norm(template[:, None] - template[None, :], axis=2)
        embedded = classical_mds(median)
        candidates = []
        for mirror in (1.0, -1.0):
            assign, _ = match_to_template(
                embedded * [1.0, 1.0, mirror], template, params.label_tolerance_mm
            )
            if (assign >= 0).sum() < 3:
                continue
            # Tracks too far from any name in the average pose still get a free name to
            # start from; the swap search then places them by their rigid partners.
            free = np.setdiff1d(np.arange(len(names)), assign[assign >= 0])
            loose = np.flatnonzero(assign < 0)[: free.size]
            assign[loose] = free[: loose.size]
            assign = refine_by_swaps(median, weight, template_distance, assign)
            ok = assign >= 0
            # The mirror image of the right correspondence swaps left and right; only the
            # right one fits the real fields with a proper rotation.
            rms = _field_fits(dense, rich, core[ok], assign[ok], template)
            candidates.append((float(np.median(rms)) if rms.size else np.inf, assign))
        if candidates:
            fit_rms, assign = min(candidates, key=lambda c: c[0])
            label_of[core[assign >= 0]] = assign[assign >= 0]
    votes = np.zeros((n_tracks, len(names)))
    # Other pieces: at each of their fields, place the core on the template by a rigid
    # fit and take the nearest template position that no core track holds there.
    for t in np.flatnonzero(label_of < 0):
        f_all = np.flatnonzero(present[t])
        for f in f_all[np.linspace(0, f_all.size - 1, min(9, f_all.size)).round().astype(int)]:
            held = np.flatnonzero((label_of >= 0) & present[:, f])
            if held.size < 3:
                continue
            r, tr = kabsch(dense[held, f], template[label_of[held]])
            p = dense[t, f] @ r.T + tr
            d = np.linalg.norm(template - p, axis=1)
            d[label_of[held]] = np.inf
            j = int(np.argmin(d))
            if d[j] <= params.label_tolerance_mm:
                votes[t, j] += 1
    for t in np.flatnonzero(label_of < 0):
        if votes[t].sum() > 0 and votes[t].max() > 0.5 * votes[t].sum():
            label_of[t] = int(votes[t].argmax())
    votes[np.arange(n_tracks)[label_of >= 0], label_of[label_of >= 0]] += 1e6

    # One label may hold several pieces if they do not overlap in time; otherwise the
    # piece with the most votes keeps it.
    first = np.array([np.flatnonzero(r)[0] for r in present])
    last = np.array([np.flatnonzero(r)[-1] for r in present])
    strength = votes[np.arange(n_tracks), np.maximum(label_of, 0)]
    for j in np.unique(label_of[label_of >= 0]):
        members = np.flatnonzero(label_of == j)
        members = members[np.argsort(-strength[members], kind="stable")]
        kept: list[int] = []
        for t in members:
            if all(last[t] < first[u] or first[t] > last[u] for u in kept):
                kept.append(int(t))
            else:
                label_of[t] = -1
    matched = np.unique(label_of[label_of >= 0])
    fits = matched.size >= params.min_label_fraction * len(names)
    if not fits:
        return Labelling(tracks, generic, False, (), names, fit_rms)

    # Join same-label pieces; unlabelled tracks keep their own group.
    group = np.where(label_of >= 0, label_of, len(names) + np.arange(n_tracks))
    joined = tracks.renumber(group)
    ids, rank, _ = numbering(tracks.field, group[tracks.track])
    new_group = np.empty(ids.size, dtype=np.int64)
    new_group[rank] = ids
    labels = []
    unlabelled = []
    extra = 0
    for i, g in enumerate(new_group):
        if g < len(names):
            labels.append(names[g])
        else:
            extra += 1
            labels.append(f"M{extra}")
            unlabelled.append(i)
    missing = tuple(n for j, n in enumerate(names) if j not in set(matched.tolist()))
    return Labelling(joined, tuple(labels), True, tuple(unlabelled), missing, fit_rms)
