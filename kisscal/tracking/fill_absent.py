"""A marker no track took, placed on its blobs' rays as context for its segment's fills.

In a lab of three cameras a marker may be seen by one camera for the whole trial (the
right ankle, which the left leg hides from the other two): it makes no 3D point, so no
track takes its name. Its blobs are still there, unused, and its segment's other markers
(heel, toe, tibia) are tracked, and so are its mirror image and theirs on the other side
(left ankle, heel, toe, tibia). A body's two sides are nearly symmetric, so the mirror
image's distances to its partners (those whose SD over the trial is at most
``rigid_fill_sd_mm``) give the absent marker's lengths, each with an SD of at least
``mirror_length_sd_mm`` (the two sides' markers are placed by hand, not mirrored).

In every field, each free blob's ray is tried: the depth where its distances to the
partners measured there fit those lengths (Gauss-Newton from each point where the ray
meets a partner's sphere). A field is placed where at least two partners are measured,
every length fits within three SDs, the expected error along the ray (the solution's
SD) is at most ``ray_length_max_error_mm`` and no other blob fits at another place
(two markers' blobs that fit are not told apart), in runs of at least
:data:`~kisscal.tracking.on_rays.MIN_RUN` fields; its blobs are taken.

The placed marker is a row of context for the fills of its partners' gaps, and, placed
in at least ``min_track_length`` fields, its name's trajectory (:func:`absent_tracks`):
those lengths are its name's alone, so a lab of three cameras names a marker one camera
sees (kiss 3: a knee the other leg hides from two cameras). Where the toe is seen by one
camera and the ankle by another, neither fixes its own depth with the heel alone (a ray
nearly square to the heel-toe line meets its sphere at a glancing angle); together, on
two rays with three lengths, they are fixed (:mod:`kisscal.tracking.fill_joint`), and the
ankle's blob is followed into the gap from the fields placed here. A name placed too
short to be named (or nowhere) is tried again once every gap is filled, its partners'
ray fills its context (:func:`~kisscal.tracking.fill_absent_again.absent_named`: a
knee whose tibia and ankle the same cameras miss); and a name whose track is measured
in too few fields to learn its own lengths (:func:`thin_names`) is placed so too,
beside its samples.

References
----------
Hartley & Zisserman 2004 (rays of a projective camera); Challis 1995 (segments as rigid
bodies of markers); Gløersen & Federolf 2016 (filling from the other markers of the
body).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from kisscal._shared import true_runs
from kisscal.dlt.model import line_offsets, ray_directions
from kisscal.tracking.bodyfill import GapFill
from kisscal.tracking.fill_donors import distance_stats
from kisscal.tracking.on_rays import path_runs
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rayfill import SpareBlobs
from kisscal.tracking.tracks import FILLED_RIGID

#: Gauss-Newton iterations of a ray's depth.
ITERS = 8

#: Largest distance (mm) between two blobs' fits for a field to count them as one place.
SAME_MM = 5.0

#: Largest distance (mm) from a blob's ray to a sample of another marker in its field
#: for the blob to be that marker's image (a camera whose blob of a measured marker no
#: point used), never the absent one's: its ray meets a sample within the noise of the
#: two (tenths of a millimetre), a merged blob's a few millimetres off either marker.
EXPLAINED_MM = 2.0

#: A placed field is off its path (:func:`off_path`) when it lies farther than this
#: from the midpoint of its two neighbours (mm) and this many times farther than either
#: neighbour from theirs: one wrong point sits twice as far from its neighbours' midpoint
#: as they do from theirs, while a real turn of the path spreads over several fields.
OFF_PATH_MM, OFF_PATH_RATIO = 20.0, 1.5


def mirror_name(name: str) -> str | None:
    """The other side's name (``L<x>`` for ``R<x>`` and back), None for a midline one."""
    if len(name) > 1 and name[0] in "LR":
        return {"L": "R", "R": "L"}[name[0]] + name[1:]
    return None


def mirror_tracks(labels: Sequence[str] | None, n_tracks: int) -> NDArray[np.int64] | None:
    """Each track's mirror image's track (by :func:`mirror_name`), -1 for none; None
    without ``labels``."""
    if labels is None:
        return None
    index = {n: k for k, n in enumerate(labels[:n_tracks])}
    return np.array([index.get(mirror_name(n) or "", -1) for n in labels[:n_tracks]])


def mirror_lengths(
    dense: NDArray, labels: Sequence[str], name: str, params: TrackingParams
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Tracks whose mirror images keep their distance to ``name``'s mirror image (SD over
    the trial at most ``rigid_fill_sd_mm``, measured together in at least
    ``body_context_fields`` fields), that distance and its SD (at least
    ``mirror_length_sd_mm``); empty when ``name``'s mirror is not tracked."""
    index = {n: i for i, n in enumerate(labels)}
    none = np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0)
    m = index.get(mirror_name(name) or "")
    if m is None:
        return none
    pairs = [
        (index[n], index[o])
        for n in labels
        if (o := mirror_name(n) or "") in index and index[o] != m and n != name
    ]
    if not pairs:
        return none
    own, other = np.array(pairs, dtype=np.int64).T
    dist = np.linalg.norm(dense[other] - dense[m][None], axis=2)  # (k, n_fields)
    seen = np.isfinite(dist)
    n = seen.sum(axis=1)
    mean = np.where(seen, dist, 0.0).sum(axis=1) / np.maximum(n, 1)
    sd = np.sqrt(np.where(seen, (dist - mean[:, None]) ** 2, 0.0).sum(axis=1) / np.maximum(n, 1))
    keep = (n >= params.length_fields) & (sd <= params.rigid_fill_sd_mm)
    return own[keep], mean[keep], np.maximum(sd[keep], params.mirror_length_sd_mm)


def _depths(
    c: NDArray, d: NDArray, p: NDArray, length: NDArray, sd: NDArray, open_ok: bool = False
) -> tuple[NDArray, NDArray, NDArray]:
    """Depth on each ray ``c + s d`` ((r, 3) each) fitting the lengths ``length`` (k,) to
    the partners ``p`` (k, r, 3; NaN where not measured), each SD ``sd`` (k,) or
    (k, r): the start of smallest worst
    residual among the points where the ray meets each partner's sphere. Returns the
    depths (r,), the worst residual in SDs (inf where another depth fits as well,
    unless ``open_ok``) and the expected error (mm) along the ray."""
    known = np.isfinite(p[..., 0])
    rel = np.where(known[..., None], p, 0.0) - c[None]  # (k, r, 3)
    b = np.einsum("krj,rj->kr", rel, d)
    root = np.sqrt(np.maximum(length[:, None] ** 2 - (np.sum(rel**2, axis=2) - b**2), 0.0))
    s = np.concatenate([b - root, b + root]).T  # (r, 2k) starts
    ok = np.concatenate([known, known]).T
    w = (1.0 / np.broadcast_to(sd.reshape(len(sd), -1), known.shape))[..., None]
    for _ in range(ITERS + 1):
        v = s[None, :, :, None] * d[None, :, None] - rel[:, :, None]  # (k, r, S, 3)
        dist = np.maximum(np.linalg.norm(v, axis=3), 1e-9)  # (k, r, S)
        res = np.where(known[..., None], (dist - length[:, None, None]) * w, 0.0)
        jac = np.where(known[..., None], np.einsum("krsj,rj->krs", v, d) / dist * w, 0.0)
        info = np.sum(jac**2, axis=0)
        step = np.sum(jac * res, axis=0) / np.maximum(info, 1e-12)
        s = s - np.clip(step, -100.0, 100.0)
    worst = np.where(ok, np.abs(res).max(axis=0), np.inf)
    best = np.argmin(worst, axis=1)
    pick = np.arange(len(s)), best
    err = 1.0 / np.sqrt(np.maximum(info[pick], 1e-12))
    # two partners' spheres meet in a circle, which a ray may cross twice: a second
    # depth that fits as well leaves the blob's place open
    other = (worst <= 3.0) & (np.abs(s - s[pick][:, None]) > SAME_MM) & (not open_ok)
    return s[pick], np.where(other.any(axis=1), np.inf, worst[pick]), err


def place_absent(
    dense: NDArray,
    partners: NDArray[np.int64],
    length: NDArray,
    sd: NDArray,
    spare: SpareBlobs,
    params: TrackingParams,
    errors: NDArray | None = None,
    own: int = -1,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The absent marker's position per field (n_fields, 3; NaN where not placed) from
    the free blobs of ``spare`` and its lengths to ``partners`` (see module), and its
    expected error along the ray (n_fields,); the blobs of the placed fields are taken.
    ``errors`` (as ``dense[..., 0]``): each partner sample's expected error (0 where
    measured), added to its length's SD. ``own``: the marker's own track in ``dense``
    (a name a track holds, :func:`thin_names`; -1 for none), whose blobs are its own."""
    out = np.full((dense.shape[1], 3), np.nan)
    along = np.full(dense.shape[1], np.nan)
    rows = np.flatnonzero(spare.free & (spare.field < dense.shape[1]))
    p = dense[partners][:, spare.field[rows]]  # (k, r, 3)
    enough = np.isfinite(p[..., 0]).sum(axis=0) >= 2
    rows, p = rows[enough], p[:, enough]
    if rows.size == 0:
        return out, along
    cam = spare.camera[rows]
    d = ray_directions(spare.dlts[cam], spare.uv_px[rows])
    c = spare.centres[cam]
    # a blob on a sampled marker's ray is that marker's image
    mine = ~explained(dense, spare.field[rows], c, d)
    rows, p, c, d = rows[mine], p[:, mine], c[mine], d[mine]
    if rows.size == 0:
        return out, along
    if errors is not None:
        e = np.nan_to_num(errors[partners][:, spare.field[rows]])
        sd = np.sqrt(sd[:, None] ** 2 + e**2)
    s, worst, err = _depths(c, d, p, length, sd)
    # another marker's own blob may keep the lengths by chance (kiss 3 seed 484: a left
    # knee's, 360 mm behind, placed the right knee, which no camera saw, 63 mm off: the
    # left knee was in a gap, that camera alone saw it); a blob that keeps a hidden
    # marker's own lengths better than these is that marker's
    claim = claimed(
        np.delete(dense, own, axis=0) if own >= 0 else dense, spare.field[rows], c, d, params
    )
    worst = np.where(claim < worst, np.inf, worst)
    # every blob that keeps the lengths is a rival, even one whose depth is too loose to
    # be placed: left out, it would leave a wrong blob alone in its field (kiss 3 seed
    # 409: a knee's own blob fit with an SD of 5.1 mm, a noise blob with 2.4 and was
    # placed 91 mm off)
    fits = worst <= 3.0
    rows, x, err = rows[fits], c[fits] + s[fits, None] * d[fits], err[fits]
    if rows.size == 0:  # no ray keeps the lengths
        return out, along
    f = spare.field[rows]
    order = np.lexsort((err, f))
    rows, x, f, err = rows[order], x[order], f[order], err[order]
    first = np.r_[True, f[1:] != f[:-1]]
    lead = np.maximum.accumulate(np.where(first, np.arange(f.size), 0))
    loose = err > params.ray_length_max_error_mm
    apart = np.linalg.norm(x - x[lead], axis=1) > SAME_MM + np.where(loose, 3.0 * err, 0.0)
    clash = np.zeros(dense.shape[1], dtype=bool)
    clash[f[apart]] = True
    first &= ~loose  # the best fit of its field, its depth fixed well enough
    one = np.zeros(dense.shape[1], dtype=bool)
    one[f[first]] = True
    one &= ~clash
    pos = np.full((dense.shape[1], 3), np.nan)
    pos[f[first]] = x[first]
    one = path_runs(_on_path(one, pos))
    keep = first & one[f]
    out[f[keep]], along[f[keep]] = x[keep], err[keep]
    spare.free[rows[one[f] & ~loose]] = False
    return out, along


def explained(dense: NDArray, field: NDArray, c: NDArray, d: NDArray) -> NDArray[np.bool_]:
    """Rays ``c + s d`` ((r, 3) each; in fields ``field``) that pass within
    :data:`EXPLAINED_MM` of a sample of ``dense`` (n, n_fields, 3; NaN where none) in
    their field, in front of their camera: the image of that marker."""
    along, off = line_offsets(dense[:, field] - c[None], d[None])  # (n, r) each
    with np.errstate(invalid="ignore"):
        return ((off <= EXPLAINED_MM) & (along > 0)).any(axis=0)


def claimed(
    dense: NDArray, field: NDArray, c: NDArray, d: NDArray, params: TrackingParams
) -> NDArray[np.float64]:
    """How well each ray ``c + s d`` ((r, 3) each; in fields ``field``) keeps the lengths
    of a marker of ``dense`` not sampled in its field (in a gap, its image one its own
    fill may need) to at least two of its own partners sampled there (markers whose
    distance to it keeps within ``rigid_fill_sd_mm`` SD over the trial): the smallest
    worst residual in SDs over those markers, where within three; inf elsewhere."""
    _, mean, sd = distance_stats(dense, dense)
    out = np.full(len(field), np.inf)
    for t in range(len(dense)):
        own = np.isfinite(sd[t]) & (sd[t] <= params.rigid_fill_sd_mm)
        own[t] = False
        if own.sum() < 2:
            continue
        p = dense[own][:, field]  # (k, r, 3)
        ask = ~np.isfinite(dense[t, field, 0]) & (np.isfinite(p[..., 0]).sum(axis=0) >= 2)
        if not ask.any():
            continue
        floor = np.maximum(sd[t, own], params.ray_length_sd_floor_mm)
        _, worst, _ = _depths(c[ask], d[ask], p[:, ask], mean[t, own], floor, open_ok=True)
        at = np.flatnonzero(ask)
        out[at] = np.minimum(out[at], np.where(worst <= 3.0, worst, np.inf))
    return out


def off_path(pos: NDArray) -> NDArray[np.bool_]:
    """Fields of ``pos`` (n_fields, 3; NaN where not placed) that jump off the path of
    their neighbours (:data:`OFF_PATH_MM`, :data:`OFF_PATH_RATIO`): a blob that fit the
    lengths in one field, away from the marker (kiss 3 seed 304: an ankle 51 mm off in
    the last field of a run). Inside a run, against the midpoint of its two neighbours;
    at a run's end, against the path continued at constant velocity from the two
    fields before (twice the miss of the neighbour's midpoint, which the neighbour
    before it does not share); not judged without the neighbours this needs."""
    dev = np.full(len(pos), np.nan)
    dev[1:-1] = np.linalg.norm(pos[1:-1] - 0.5 * (pos[:-2] + pos[2:]), axis=1)
    back, back2 = np.r_[np.nan, dev[:-1]], np.r_[np.nan, np.nan, dev[:-2]]
    ahead, ahead2 = np.r_[dev[1:], np.nan], np.r_[dev[2:], np.nan, np.nan]
    placed = np.isfinite(pos[:, 0])
    last = placed & ~np.r_[placed[1:], False]
    first = placed & ~np.r_[False, placed[:-1]]
    # NaN (no judgement) where a neighbour has no midpoint of its own
    near = np.maximum(back, ahead)
    with np.errstate(invalid="ignore"):
        inside = (dev > OFF_PATH_MM) & (dev > OFF_PATH_RATIO * near)
        after = last & (2 * back > OFF_PATH_MM) & (back > OFF_PATH_RATIO * back2)
        before = first & (2 * ahead > OFF_PATH_MM) & (ahead > OFF_PATH_RATIO * ahead2)
    return inside | after | before


def _on_path(one: NDArray, pos: NDArray) -> NDArray[np.bool_]:
    """``one`` (n_fields,) without the fields :func:`off_path` finds, again on what is
    left (a wrong field next to a run's end makes the end look off its path first)."""
    for _ in range(3):
        off = off_path(np.where(one[:, None], pos, np.nan))
        if not off.any():
            break
        one = one & ~off
    return one


def absent_placed(
    dense: NDArray,
    labels: Sequence[str] | None,
    missing: Sequence[str],
    spare: SpareBlobs | None,
    params: TrackingParams,
    errors: NDArray | None = None,
) -> tuple[list[tuple[str, NDArray[np.int64]]], NDArray[np.float64], NDArray[np.float64]]:
    """Per name of ``missing`` that :func:`place_absent` places, its name and partners,
    its row ((m, n_fields, 3); m = 0 without ``spare``) and each placed field's expected
    error along its ray ((m, n_fields), NaN where not placed). Only names
    placed somewhere have a row; a row placed is a partner of the names placed after
    it, which are tried again while rows are added (kiss 3: an ankle that one camera
    sees, placed by its heel and toe, and its knee, which another camera sees, by the
    ankle and the tibia); a row placed in fewer than ``min_track_length`` fields (too
    few to be named) waits until no other is added, its blobs free. ``errors``: see
    :func:`place_absent` (placed rows' own added as they are)."""
    rows, sds, who = [], [], []
    names = list(labels or ())
    waiting = list(missing) if spare is not None and labels else []
    last = False  # a row too short to be named is kept only once no other is added
    while waiting:
        left = []
        for name in waiting:
            partners, length, sd = mirror_lengths(dense, names, name, params)
            row = np.full(dense.shape[1:], np.nan)
            if partners.size >= 2:
                free = spare.free.copy()
                own = names.index(name) if name in names[: len(dense)] else -1
                row, err = place_absent(dense, partners, length, sd, spare, params, errors, own)
            n = np.isfinite(row[:, 0]).sum()
            if n == 0 or (n < params.min_track_length and not last):
                # its blobs wait for the partners placed after it (kiss 3 seed 321: the
                # knee, 5 fields by tibia and thigh, 22 with the ankle placed in 210)
                if n:
                    spare.free[:] = free
                left.append(name)
                continue
            rows.append(row)
            sds.append(err)
            who.append((name, partners))
            dense = np.concatenate([dense, row[None]])
            if errors is not None:
                errors = np.concatenate([errors, err[None]])
            names.append(name)
        if len(left) == len(waiting):
            if last:
                break
            last = True
        waiting = left
    if not rows:
        return [], np.zeros((0, *dense.shape[1:])), np.zeros((0, dense.shape[1]))
    return who, np.stack(rows), np.stack(sds)


def thin_names(dense: NDArray, labels: Sequence[str] | None, params: TrackingParams) -> list[str]:
    """Names of tracks of ``dense`` (measured samples; one label each) measured in
    fewer than ``length_fields`` fields, with a mirror name: too few to learn their own
    lengths, so no fill places them on their rays beyond their samples, while their
    mirror images' lengths can (kiss 3 seed 439: a 5-field piece named LANK, the ankle
    one camera sees in 278 fields, and its knee left without partners)."""
    count = np.isfinite(dense[..., 0]).sum(axis=1)
    return [
        n
        for n, c in zip(labels or (), count, strict=False)
        if c < params.length_fields and mirror_name(n) is not None
    ]


def absent_rows(
    dense: NDArray,
    labels: Sequence[str] | None,
    missing: Sequence[str],
    spare: SpareBlobs | None,
    params: TrackingParams,
) -> tuple[list[tuple[str, NDArray[np.int64]]], NDArray[np.float64], NDArray[np.float64]]:
    """:func:`absent_placed` of ``missing``, then of :func:`thin_names` with those rows
    as partners: a thin name's marker may be one no camera sees, and a missing name's
    blobs fit its lengths by chance (a thigh's whose knee waits for its ankle, kiss 3
    seed 321), so it takes only the blobs the missing names leave."""
    who, rows, sds = absent_placed(dense, labels, missing, spare, params)
    thin = thin_names(dense, labels, params)
    if not thin or spare is None or not labels:
        return who, rows, sds
    names = [*labels[: len(dense)], *(w[0] for w in who)]
    more = absent_placed(np.concatenate([dense, rows]), names, thin, spare, params)
    return [*who, *more[0]], np.concatenate([rows, more[1]]), np.concatenate([sds, more[2]])


def absent_tracks(
    who: list[tuple[str, NDArray[np.int64]]],
    rows: NDArray,
    sds: NDArray,
    first_track: int,
    params: TrackingParams,
) -> tuple[list[str], list[tuple[NDArray, GapFill]]]:
    """The rows of :func:`absent_placed` placed in at least ``min_track_length`` fields
    (a piece long enough to be named) as tracks numbered from ``first_track``: their
    names, and one (xyz, fill) per run, ``filled_rigid`` on the rays of one camera,
    expecting the run's RMS error along them, its partners the donors."""
    names, out = [], []
    for (name, partners), row, sd in zip(who, rows, sds, strict=True):
        donors = tuple(partners[partners < first_track].tolist())  # not the absent rows
        placed = np.isfinite(row[:, 0])
        if placed.sum() < params.min_track_length:
            continue
        out += ray_runs(first_track + len(names), row, sd, placed, donors)
        names.append(name)
    return names, out


def ray_runs(
    t: int, row: NDArray, sd: NDArray, where: NDArray, donors: tuple[int, ...]
) -> list[tuple[NDArray, GapFill]]:
    """One (xyz, fill) of track ``t`` per run of ``where`` in ``row`` (n_fields, 3),
    ``filled_rigid`` on the rays of one camera, expecting the run's RMS of ``sd``."""
    out = []
    for a, b in zip(*true_runs(where), strict=True):
        err = float(np.sqrt(np.mean(sd[a:b] ** 2)))
        out.append((row[a:b], GapFill(t, a, b - a, FILLED_RIGID, err, donors, b - a)))
    return out
