"""Automatic recognition of the calibration rods' markers in one camera's blobs.

Shafiq et al. 2001, section 3.3: the calibration volume is enclosed by four hanging rods
with six markers each, "placed in a unique configuration on each rod so that a particular
rod can be automatically recognised". kisscal recognises them as follows.

1. A rod is a straight line in 3D, so its markers lie on a line in the linearised image:
   every pair of blobs proposes a line; blobs within ``rod_line_tol_px`` of it are its
   members (noise and strobe blobs included, filtered later).
2. Along that line, a perspective camera maps the rod's 1D marker positions ``s`` (mm
   from the top marker) to image positions ``t`` by a 1D projectivity
   ``t = (a s + b) / (c s + 1)``: three correspondences fix it and every further marker
   must then fall where the cross-ratios of the rod's spacings put it (a projective
   invariant, unchanged by the camera's pose and non-square pixels). Every choice of
   three rod markers and three blobs on the line (in the same order, top down) is
   tried; the hypothesis explaining the most blobs within ``rod_fit_tol_px``, then with
   the least RMS, identifies and orders that rod on that line.
3. The rods are assigned greedily (most markers, then smallest residual), each blob used
   once. If a competing hypothesis explains as many markers almost as well (another blob
   set for the same rod, the same blobs as another rod, or a shifted assignment), the
   camera is refused with a message naming the rods: never a silent guess.

4. Blobs left over that still form a rod-like line (``rod_min_markers`` blobs on a line,
   parallel to and as long as the recognised rods' lines) refuse the camera: a rod hangs
   there that ``[[rods.rod]]`` does not list (``DltParams.rod_refuse_unlisted``).

A rod configuration is refused up front when its spacings are not projectively distinct
(:func:`validate_rods`), since then no image could tell the rods apart.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points
from kisscal.dlt.params import DEFAULT_PARAMS, DltParams, Rod, RodMatch, marker_label
from kisscal.dlt.rod_geometry import (
    apply_projectivity,
    fit_projectivity,
    monotone_subsets,
    rod_positions,
    validate_rods,
)
from kisscal.errors import EstimationFailed, InputError


def make_rods(config: Sequence[tuple[str, ArrayLike]]) -> tuple[Rod, ...]:
    """Rods from ``(name, points_mm)`` pairs (``[[rods.rod]]`` of session.toml), checked.

    Raises
    ------
    KisscalError
        Duplicate names, fewer than 4 markers, markers not top to bottom along a straight
        rod, or coincident markers.
    """
    rods = []
    names: set[str] = set()
    for name, pts in config:
        p = np.asarray(pts, dtype=float)
        if name in names:
            raise InputError(f"rods: rod name {name!r} is used twice")
        names.add(name)
        if p.ndim != 2 or p.shape[1] != 3 or len(p) < 4:
            raise InputError(
                f"rods: rod {name} needs at least 4 markers as [x, y, z], got {p.shape}"
            )
        if not np.isfinite(p).all():
            raise InputError(f"rods: rod {name} has non-finite marker coordinates")
        s, off = rod_positions(p)
        length = s[-1]
        if length <= 0 or np.any(np.diff(s) <= 1e-3 * length):
            raise InputError(
                f"rods: markers of rod {name} must be distinct and listed top to bottom"
            )
        if off.max() > 0.02 * length:
            raise InputError(
                f"rods: rod {name} is not straight (a marker lies {off.max():.1f} mm off its line)"
            )
        if p[0, 2] < p[-1, 2]:
            raise InputError(f"rods: markers of rod {name} must be listed top to bottom")
        rods.append(Rod(name=str(name), points_mm=p))
    if not rods:
        raise InputError("rods: no [[rods.rod]] given")
    return tuple(rods)


_PAIRS_PER_CHUNK = 4096


def chance_alignments(uv: NDArray[np.float64], tol_px: float) -> float:
    """Stray blobs expected within ``tol_px`` of a line across the blobs' extent.

    ``(n - 2) * 2 tol * diagonal / area`` of the blobs' bounding box: with blobs spread
    evenly, the number a line through two of them collects by chance. Near 1 and above,
    chance lines of ``rod_min_markers`` blobs outnumber the rods.
    """
    if len(uv) < 3:
        return 0.0
    w, h = np.ptp(uv, axis=0) + 2 * tol_px
    return (len(uv) - 2) * 2 * tol_px * float(np.hypot(w, h)) / float(w * h)


def _check_busy(uv: NDArray[np.float64], params: DltParams, camera: str) -> None:
    """Refuse a rod image too busy to find rods by their alignment, before any work."""
    chance = chance_alignments(uv, params.rod_line_tol_px)
    if chance > params.rod_max_chance_blobs:
        raise EstimationFailed(
            f"camera {camera}: {len(uv)} blobs in the rod image, too many to find the rods:"
            f" a line through two blobs passes within {params.rod_line_tol_px:g} px of"
            f" {chance:.1f} others by chance (at most {params.rod_max_chance_blobs:g});"
            " raise the detection threshold or mask the clutter"
        )


def _candidate_lines(
    uv: NDArray[np.float64], params: DltParams, camera: str = ""
) -> list[NDArray[np.int64]]:
    """Sets of blobs lying on a common line, each sorted top-down along the line.

    Every pair of blobs proposes a line, in chunks (memory ~ chunk x blobs); more than
    ``params.rod_max_lines`` distinct lines refuse the image as too busy.
    """
    n = len(uv)
    i_all, j_all = np.triu_indices(n, k=1)
    rows: set[bytes] = set()
    for lo in range(0, len(i_all), _PAIRS_PER_CHUNK):
        i, j = i_all[lo : lo + _PAIRS_PER_CHUNK], j_all[lo : lo + _PAIRS_PER_CHUNK]
        d = uv[j] - uv[i]
        length = np.linalg.norm(d, axis=1)
        ok = length > 2 * params.rod_line_tol_px
        i, d, length = i[ok], d[ok], length[ok]
        normal = np.stack([-d[:, 1], d[:, 0]], axis=1) / length[:, None]
        dist = np.abs((uv[None, :, :] - uv[i][:, None, :]) @ normal[:, :, None])[..., 0]
        members = dist < params.rod_line_tol_px
        members = members[members.sum(axis=1) >= params.rod_min_markers]
        rows.update(bytes(r) for r in np.packbits(members, axis=1))
        if len(rows) > params.rod_max_lines:
            raise EstimationFailed(
                f"camera {camera}: more than {params.rod_max_lines} lines of"
                f" {params.rod_min_markers} or more blobs among {n} blobs in the rod image:"
                " too busy to tell rods from chance alignments; raise the detection"
                " threshold or mask the clutter"
            )
    lines = []
    for packed in sorted(rows):
        row = np.unpackbits(np.frombuffer(packed, dtype=np.uint8), count=n).astype(bool)
        idx = np.flatnonzero(row)
        # Refit the line to its members (total least squares) and take the members again.
        centre = uv[idx].mean(axis=0)
        direction = np.linalg.svd(uv[idx] - centre)[2][0]
        normal_fit = np.array([-direction[1], direction[0]])
        near = np.abs((uv - centre) @ normal_fit) < params.rod_line_tol_px
        idx = np.flatnonzero(near | row)
        if direction[1] < 0:
            direction = -direction
        order = np.argsort((uv[idx] - centre) @ direction)
        lines.append(idx[order])
    unique = {tuple(x) for x in lines}
    return [np.array(x, dtype=np.int64) for x in sorted(unique)]


def _rod_hypotheses(
    t: NDArray[np.float64], s: NDArray[np.float64], params: DltParams, scale: float
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Assignments of line positions ``t`` (px, sorted) to rod positions ``s`` (0..1).

    Returns ``(assign (H, k) line index or -1, rms_px (H,), gap_px (H, k))`` for the
    distinct hypotheses with at least ``params.rod_min_markers`` markers, best first
    (most markers, then least RMS); ``gap_px`` is each marker's distance along the line
    from its predicted position (NaN where unmatched).
    """
    m, k = len(t), len(s)
    tn = (t - t[0]) / scale
    tol = params.rod_fit_tol_px / scale
    sub_s = monotone_subsets(k, 3)
    sub_t = monotone_subsets(m, 3)
    pairs_t = sub_t if params.rods_upright else np.concatenate([sub_t, sub_t[:, ::-1]])
    ii, jj = np.meshgrid(np.arange(len(sub_s)), np.arange(len(pairs_t)), indexing="ij")
    S3 = s[sub_s[ii.ravel()]]
    T3 = tn[pairs_t[jj.ravel()]]
    h = fit_projectivity(S3, T3, np.ones_like(S3))
    # A pole of the projectivity between the rod's ends would fold the rod: impossible.
    den = h[:, 2:3] * np.array([s[0], s[-1]]) + 1.0
    h = h[np.all(den > 0, axis=1) | np.all(den < 0, axis=1)]
    assign = np.full((len(h), k), -1, dtype=np.int64)
    for _ in range(2):  # match, refit on all matches, match again
        pred = apply_projectivity(h, np.broadcast_to(s, (len(h), k)))
        gap = np.abs(pred[:, :, None] - tn[None, None, :])
        nearest = gap.argmin(axis=2)
        hit = np.take_along_axis(gap, nearest[..., None], axis=2)[..., 0] < tol
        assign = np.where(hit, nearest, -1)
        enough = hit.sum(axis=1) >= 3
        h, assign, w = h[enough], assign[enough], hit[enough].astype(float)
        if not len(h):
            break
        h = fit_projectivity(np.broadcast_to(s, w.shape), tn[np.maximum(assign, 0)], w)
    empty = np.empty((0, k))
    if not len(h):
        return empty.astype(np.int64), np.empty(0), empty
    pred = apply_projectivity(h, np.broadcast_to(s, (len(h), k)))
    w = assign >= 0
    gap = np.where(w, np.abs(pred - tn[np.maximum(assign, 0)]) * scale, np.nan)
    n = w.sum(axis=1)
    # The markers must keep their order along the line: one blob each, top down.
    good = (n >= params.rod_min_markers) & _strictly_increasing(assign)
    if not params.rods_upright:
        flipped = np.where(w, m - 1 - assign, -1)
        good |= (n >= params.rod_min_markers) & _strictly_increasing(flipped)
    rms = np.sqrt(np.nansum(gap**2, axis=1) / np.maximum(n, 1))
    assign, rms, n, gap = assign[good], rms[good], n[good], gap[good]
    if not len(assign):
        return assign, rms, gap
    assign, first = np.unique(assign, axis=0, return_index=True)
    rms, n, gap = rms[first], n[first], gap[first]
    order = np.lexsort((rms, -n))
    return assign[order], rms[order], gap[order]


@dataclass
class _Candidate:
    """The best identification of one rod on one candidate line."""

    rod: int
    blobs: NDArray[np.int64]  # blob index per rod marker, -1 if not matched
    rms_px: float
    # Blob sets of other orderings of the same line that fit as well (shifted patterns)
    rivals: list[set[int]] = field(default_factory=list)

    @property
    def n(self) -> int:
        return int((self.blobs >= 0).sum())

    @property
    def blob_set(self) -> set[int]:
        return set(self.blobs[self.blobs >= 0].tolist())


def _line_candidates(
    line: NDArray[np.int64], uv: NDArray[np.float64], rod_s: list, params: DltParams
) -> list[_Candidate]:
    """Best hypothesis per rod on one line, with the rivals resolved or flagged."""
    p = uv[line]
    direction = p[-1] - p[0]
    t = (p - p[0]) @ (direction / np.linalg.norm(direction))
    scale = max(t[-1] - t[0], 1e-9)
    out = []
    for ir, s in enumerate(rod_s):
        assign, rms, gap = _rod_hypotheses(t, s, params, scale)
        if not len(assign):
            continue
        best = assign[0].copy()
        n0 = int((best >= 0).sum())
        rivals = []
        drop = np.zeros(len(best), dtype=bool)
        for a, r, g in zip(assign[1:], rms[1:], gap[1:], strict=True):
            if int((a >= 0).sum()) != n0 or r >= _near(rms[0], params):
                continue
            # Line blobs both hypotheses use: given another marker index, the pattern
            # fits shifted along the rod (an ordering doubt, judged in _check_ambiguity).
            shared = np.intersect1d(a[a >= 0], best[best >= 0])
            if any(np.flatnonzero(a == x)[0] != np.flatnonzero(best == x)[0] for x in shared):
                rivals.append({int(line[x]) for x in a[a >= 0]})
                continue
            # Otherwise another blob stands in for some marker: keep the best hypothesis'
            # blob only when it is clearly nearer the prediction, else leave the marker
            # unidentified (two blobs this close would merge in a real image anyway).
            swapped = (a >= 0) & (best >= 0) & (a != best)
            drop |= swapped & (g < np.array([_near(x, params) for x in gap[0]]))
        best[drop] = -1
        blobs = np.where(best >= 0, line[np.maximum(best, 0)], -1)
        out.append(_Candidate(ir, blobs, float(rms[0]), rivals))
    return out


def recognise_rods(
    uv_px: ArrayLike,
    rods: Sequence[Rod],
    params: DltParams = DEFAULT_PARAMS,
    camera: str = "",
) -> RodMatch:
    """Identify and order the calibration rods' markers among one camera's blobs.

    Shafiq et al. 2001, section 3.3 (rods recognised by their unique configuration);
    method in the module docstring.

    Parameters
    ----------
    uv_px : array_like, shape (N, 2)
        Linearised blob centroids of a rod image (rod markers plus strobes and noise).
    rods : sequence of Rod
        The configured rods (:func:`make_rods`), markers top to bottom.
    params : DltParams
        ``rod_*`` tolerances.
    camera : str
        Camera id, named in messages.

    Returns
    -------
    RodMatch
        Blob index per rod marker (-1 when not found) and what is missing.

    Raises
    ------
    KisscalError
        Non-unique rod spacings (:func:`validate_rods`), an image too busy to search
        (``rod_max_chance_blobs``, ``rod_max_lines``: see :func:`chance_alignments`), an
        ambiguous identification (message names the camera and rods), or, with
        ``params.rod_refuse_unlisted``, a rod-like line of left-over blobs that matches no
        configured rod (a rod missing from ``[[rods.rod]]``).
    """
    uv = as_points(uv_px, 2, "uv_px")
    validate_rods(rods, params)
    finite = np.flatnonzero(np.isfinite(uv).all(axis=1))
    uvf = uv[finite]
    rod_s = [rod_positions(r.points_mm)[0] for r in rods]
    rod_s = [s / s[-1] for s in rod_s]
    cands: list[_Candidate] = []
    _check_busy(uvf, params, camera)
    if len(uvf) >= params.rod_min_markers:
        for line in _candidate_lines(uvf, params, camera):
            cands += _line_candidates(line, uvf, rod_s, params)
    cands = [c for c in cands if c.n >= params.rod_min_markers]
    cands.sort(key=lambda c: (-c.n, c.rms_px))

    chosen: dict[int, _Candidate] = {}
    used: set[int] = set()
    for c in cands:
        if c.rod in chosen or c.blob_set & used:
            continue
        chosen[c.rod] = c
        used |= c.blob_set
    _check_ambiguity(chosen, cands, rods, params, camera)
    if params.rod_refuse_unlisted:
        _check_unlisted(uvf, chosen, rods, params, camera)

    n_markers = max(len(r.points_mm) for r in rods)
    blob_index = np.full((len(rods), n_markers), -1, dtype=np.int64)
    fit_rms = np.full(len(rods), np.nan)
    missing = []
    for ir, rod in enumerate(rods):
        k = len(rod.points_mm)
        if ir in chosen:
            b = chosen[ir].blobs
            blob_index[ir, :k] = np.where(b >= 0, finite[np.maximum(b, 0)], -1)
            fit_rms[ir] = chosen[ir].rms_px
        missing += [marker_label(rod.name, i) for i in range(k) if blob_index[ir, i] < 0]
    unused = np.setdiff1d(np.arange(len(uv)), blob_index[blob_index >= 0])
    return RodMatch(
        camera=camera,
        rod_names=tuple(r.name for r in rods),
        blob_index=blob_index,
        fit_rms_px=fit_rms,
        missing=tuple(missing),
        unused_blobs=unused,
    )


def _check_ambiguity(
    chosen: dict[int, _Candidate],
    cands: list[_Candidate],
    rods: Sequence[Rod],
    params: DltParams,
    camera: str,
) -> None:
    """Refuse when a rival explains a chosen rod's markers as well (never guess silently)."""
    for ia, a in chosen.items():
        name = rods[ia].name
        others = set().union(*(c.blob_set for i, c in chosen.items() if i != ia))
        # A rival ordering that borrows blobs another rod explains is no rival.
        if any(not (r - a.blob_set) & others for r in a.rivals):
            raise EstimationFailed(
                f"camera {camera}: the markers of rod {name} fit two different orderings "
                "equally well; refusing to guess"
            )
        for c in cands:
            if c is a or c.n != a.n or c.rms_px >= _near(a.rms_px, params):
                continue
            if c.rod == ia and not c.blob_set & a.blob_set and not c.blob_set & others:
                raise EstimationFailed(
                    f"camera {camera}: rod {name} matches two different sets of {a.n} blobs "
                    f"equally well ({a.rms_px:.2f} px and {c.rms_px:.2f} px); refusing to guess"
                )
            b = chosen.get(c.rod)
            if c.rod != ia and len(c.blob_set & a.blob_set) >= 3 and (b is None or b.n < c.n):
                raise EstimationFailed(
                    f"camera {camera}: the same {a.n} blobs fit rods {name} and "
                    f"{rods[c.rod].name} equally well ({a.rms_px:.2f} px and {c.rms_px:.2f} px); "
                    "refusing to guess"
                )


def _check_unlisted(
    uv: NDArray[np.float64],
    chosen: dict[int, _Candidate],
    rods: Sequence[Rod],
    params: DltParams,
    camera: str,
) -> None:
    """Refuse a rod-like line among the blobs no rod explains (a rod missing from the config).

    The rods hang plumb side by side (Shafiq et al. 2001, section 3.3), so in one image
    their lines are nearly parallel and of one length scale. Left-over blobs forming such
    a line of at least ``rod_min_markers`` blobs are most likely a rod the configuration
    does not list; calibrating without it would silently discard a quarter of the control
    points. Stray strobes, noise and LED rings seldom line up five times within
    ``rod_line_tol_px``, and when they do they are rarely parallel to the rods and of
    their length as well.

    Raises
    ------
    KisscalError
        Naming the camera, the number of blobs and where the line is (``u``, px).
    """
    if not chosen:
        return  # nothing to compare a line with: the DLT then fails for lack of points
    used = set().union(*(c.blob_set for c in chosen.values()))
    spare = np.setdiff1d(np.arange(len(uv)), np.fromiter(used, dtype=np.int64))
    if len(spare) < params.rod_min_markers:
        return
    # Recognised rods' image lines: unit directions (sign-free) and lengths, first to last
    # identified marker.
    ends = np.array([uv[c.blobs[c.blobs >= 0][[0, -1]]] for c in chosen.values()])
    rod_dir = ends[:, 1] - ends[:, 0]
    rod_len = np.linalg.norm(rod_dir, axis=1)
    rod_dir = rod_dir / rod_len[:, None]
    ratio = params.rod_unlisted_length_ratio
    cos_tol = np.cos(np.deg2rad(params.rod_unlisted_angle_deg))
    lines = _candidate_lines(uv[spare], params, camera)
    for line in sorted(lines, key=len, reverse=True):
        p = uv[spare[line]]
        d = p[-1] - p[0]
        length = float(np.linalg.norm(d))
        if length <= 0:
            continue
        parallel = np.abs(rod_dir @ (d / length)).max() >= cos_tol
        if parallel and rod_len.min() / ratio <= length <= rod_len.max() * ratio:
            unseen = [rods[i].name for i in range(len(rods)) if i not in chosen]
            hint = "is a rod missing from session.toml?"
            if unseen:
                names = ", ".join(unseen)
                hint = f"is a rod missing from session.toml, or are points_mm of {names} wrong?"
            raise EstimationFailed(
                f"camera {camera}: {len(line)} blobs on a line near u={p[:, 0].mean():.0f} px "
                f"match no rod in [[rods.rod]] ({hint})"
            )


def _strictly_increasing(assign: NDArray[np.int64]) -> NDArray[np.bool_]:
    """Rows whose non-negative entries are strictly increasing (-1 entries are skipped)."""
    running = np.maximum.accumulate(assign, axis=1)
    previous = np.concatenate([np.full((len(assign), 1), -1), running[:, :-1]], axis=1)
    return np.all((assign < 0) | (assign > previous), axis=1)


def _near(rms: float, params: DltParams) -> float:
    """Residual below which a rival hypothesis counts as fitting as well as ``rms``."""
    return params.rod_ambiguity_ratio * max(rms, 0.05 * params.rod_fit_tol_px)
