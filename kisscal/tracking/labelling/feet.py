"""A last contest for each foot's names, judged by distances to the shank.

Labelling matches positions to a standing template; a walking foot sits on average 80-130
mm behind where the standing pose puts it, so the one-to-one match can hand the ankle's
name to the heel's trajectory and the toe's to the ankle's (a real Vicon walk). The
distances between a foot's markers and from them to the shank's do not depend on the
pose: heel to toe is the foot's length, the ankle is the shank marker's neighbour. Each
side's ankle, heel and toe names are re-assigned among the trajectories holding them and
the unnamed ones near the shank, when another assignment fits the template's distances
far better than the labelling's own.
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from itertools import permutations

import numpy as np
from numpy.typing import NDArray

from kisscal.markersets.model import MarkerSet
from kisscal.tracking.labelling.result import Labelling
from kisscal.tracking.labelling.state import median_distances

#: Another assignment replaces the labelling's own when its mean squared relative distance
#: error is at most this share of the labelling's.
_BETTER = 0.25
#: Unnamed trajectories farther than this many times the template's farthest foot-to-shank
#: distance from a shank marker (median) do not take part.
_NEAR = 1.5
#: At most this many unnamed trajectories (the most often seen) take part.
_MOST = 4


def _shank(marker_set: MarkerSet, foot: tuple[str, ...]) -> tuple[str, ...]:
    """Names joined to the foot's by a segment or a hinge that are not the foot's."""
    pairs = tuple(marker_set.segments) + tuple(marker_set.hinge_segments)
    out = {b if a in foot else a for a, b in pairs if (a in foot) != (b in foot)}
    return tuple(n for n in marker_set.names if n in out)


def _error(dist: NDArray, target: NDArray) -> NDArray:
    """Mean squared relative error per assignment; infinite when a pair of its
    trajectories is never seen together (a piece that fits by seeing little)."""
    rel = ((dist - target) / target) ** 2
    seen = np.isfinite(rel).all(axis=-1)
    return np.where(seen, np.where(seen[..., None], rel, 0.0).mean(axis=-1), np.inf)


def _distances(dense: NDArray, tracks: NDArray) -> NDArray:
    """Median distance between every pair of ``tracks`` over the trial (NaN: never seen
    together)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return median_distances(dense, tracks, np.arange(dense.shape[1]))


def _foot_pairs(n: int, n_ref: int) -> tuple[NDArray, NDArray]:
    """Index pairs (i < j) of ``n`` names, the first ``n_ref`` the shank's, with a foot name."""
    i, j = np.triu_indices(n, 1)
    keep = j >= n_ref
    return i[keep], j[keep]


def _contest(
    d: NDArray, ref: NDArray, cands: NDArray, held: NDArray, target: NDArray
) -> NDArray | None:
    """The best assignment of the foot's names (rows of ``target``) to ``cands`` (columns
    of ``d`` beyond the ``ref`` ones), or None when the held one is as good."""
    k = target.shape[0] - ref.size
    choices = np.array(list(permutations(range(cands.size), k)), dtype=np.int64)
    if choices.size == 0:
        return None
    cols = np.concatenate([np.broadcast_to(np.arange(ref.size), (len(choices), ref.size)),
                           ref.size + choices], axis=1)  # fmt: skip
    dist = d[cols[:, :, None], cols[:, None, :]]
    # Pairs with a foot name (the shank's own distance is the same in every assignment).
    iu = _foot_pairs(target.shape[0], ref.size)
    score = _error(dist[:, iu[0], iu[1]], target[iu])
    best = int(np.argmin(score))
    own = np.flatnonzero((choices == np.searchsorted(cands, held)[None, :]).all(axis=1))
    if (held < 0).any() or own.size == 0:
        # The labelling left a name free: it is scored over the names it gave.
        given = np.flatnonzero(held >= 0)
        sub = np.concatenate([np.arange(ref.size), ref.size + given])
        cols_h = np.concatenate(
            [np.arange(ref.size), ref.size + np.searchsorted(cands, held[given])]
        )
        dist_h = d[cols_h[:, None], cols_h[None, :]]
        iu_h = _foot_pairs(sub.size, ref.size)
        own_score = float(_error(dist_h[iu_h], target[np.ix_(sub, sub)][iu_h]))
    else:
        own_score = float(score[own[0]])
    # Held names never seen together cannot be compared: they stay.
    if not np.isfinite(own_score) or score[best] > _BETTER * own_score:
        return None
    return cands[choices[best]]


def foot_contest(labelling: Labelling, marker_set: MarkerSet) -> Labelling:
    """Re-assign each foot's ankle, heel and toe names where the distances among the
    foot's trajectories and to the shank's fit the set's template (scaled to the
    labelling's stature) at most :data:`_BETTER` times as badly as the labelling's own.

    References
    ----------
    Winter 2009 (segment lengths proportional to stature, which the scaled template
    assumes).
    """
    if not labelling.fits_marker_set or labelling.tracks.n_tracks == 0:
        return labelling
    height = labelling.height_mm
    template = marker_set.scaled(height).template_mm if np.isfinite(height) else None
    if template is None:
        return labelling
    labels = list(labelling.labels)
    unnamed = np.array(labelling.unlabelled, dtype=np.int64)
    dense = labelling.tracks.positions()
    seen = np.isfinite(dense[..., 0]).sum(axis=1)
    changed = False
    for side in ("left", "right"):
        foot = tuple(n for n in marker_set.foot(side).values() if n in marker_set.names)
        shank = tuple(n for n in _shank(marker_set, foot) if n in labels)
        if len(foot) < 2 or not shank:
            continue
        ref = np.array([labels.index(n) for n in shank])
        held = np.array([labels.index(n) if n in labels else -1 for n in foot])
        idx = [marker_set.index(n) for n in shank + foot]
        target = np.linalg.norm(template[idx][:, None] - template[idx][None, :], axis=2)
        cands = _candidates(dense, ref, held, unnamed, seen, target[: ref.size, ref.size :])
        if cands.size < len(foot):
            continue
        d = _distances(dense, np.concatenate([ref, cands]))
        best = _contest(d, ref, cands, held, target)
        if best is None:
            continue
        labels = _rename(labels, foot, held, best)
        changed = True
    if not changed:
        return labelling
    return _relabelled(labelling, labels, marker_set.names)


def _candidates(
    dense: NDArray, ref: NDArray, held: NDArray, unnamed: NDArray, seen: NDArray, reach: NDArray
) -> NDArray[np.int64]:
    """The trajectories holding the foot's names and up to :data:`_MOST` unnamed ones
    (the most often seen) within :data:`_NEAR` times the farthest foot-to-shank distance
    of every shank marker, sorted."""
    pool = unnamed[seen[unnamed] > 0] if unnamed.size else unnamed
    if pool.size:
        d = _distances(dense, np.concatenate([ref, pool]))
        d = d[: ref.size, ref.size :]
        near = (d <= _NEAR * reach.max(axis=1)[:, None]).all(axis=0)
        pool = pool[near]
        pool = pool[np.argsort(-seen[pool], kind="stable")[:_MOST]]
    return np.unique(np.concatenate([held[held >= 0], pool]))


def _rename(labels: list[str], foot: tuple[str, ...], held: NDArray, best: NDArray) -> list[str]:
    """``labels`` with ``foot[i]`` on trajectory ``best[i]``; a trajectory that loses a
    foot name and gets none is unnamed (an ``M`` name after the highest in use)."""
    out = list(labels)
    for t in held[held >= 0]:
        out[t] = ""
    for name, t in zip(foot, best, strict=True):
        out[t] = name
    used = [int(x[1:]) for x in labels if x.startswith("M") and x[1:].isdigit()]
    k = max(used, default=0)
    for t in range(len(out)):
        if out[t] == "":
            k += 1
            out[t] = f"M{k}"
    return out


def _relabelled(labelling: Labelling, labels: list[str], names: tuple[str, ...]) -> Labelling:
    unlabelled = tuple(t for t, n in enumerate(labels) if n not in names)
    missing = tuple(n for n in names if n not in labels)
    return replace(labelling, labels=tuple(labels), unlabelled=unlabelled, missing=missing)
