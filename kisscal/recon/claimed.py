"""Two-camera trajectories made of rays that other trajectories claim.

Two markers each seen by one camera give two rays; when the rays cross within the
epipolar band they make a point. When the two markers move together (the pelvis markers,
a foot's markers) that point moves smoothly too, and passes the continuity check of
:mod:`kisscal.recon.pairs` for as long as each marker stays seen by its one camera: a ghost
trajectory, hundreds of millimetres from either marker. It begins (or ends) where the
two markers lose (or gain) their second camera, so that at its first field the
trajectories the markers leave behind predict positions on its rays, far from its point:
the tracker's prediction explains each ray by another marker (Küçük 2005, 3.4: the
constant-velocity prediction gate). A true marker's trajectory begins where its own
trajectory is absent; its ray may pass by another marker's prediction only where the two
images overlap. A ghost also ends where one of its markers gains a second camera: the
marker's own pair begins there, sharing the ghost's blob, and the marker's trajectory,
continued back into the ghost's last field, lands on that pair (one claimed ray, backed
by the blob's true pair, from a trajectory that outlasts the piece). Markers lost a
while before the piece begins (two iliac spine markers seen by no camera for half a
second, then each by one) leave no trajectory that ends there; a marker of their rigid
body that stays in view carries them (:mod:`kisscal.recon.carried`), and their carried
positions claim the rays as the predictions do.

:func:`claimed_pieces` finds such pieces of two-camera points (points of one camera pair
in consecutive fields, each within a field's step of the last) so that the caller can
withdraw their pairs and let the blobs' true pairs compete again.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from kisscal.dlt.model import pixel_size_mm, project_rows
from kisscal.recon.carried import carried, links
from kisscal.recon.group import embed_fields
from kisscal.recon.params import ReconParams

#: Consecutive positions by which the continuity check
#: (:func:`kisscal.recon.pairs.continuity_mm`) judges a point: a known run shorter than
#: this proves no continuity, so it does not outlast a piece (:func:`_known_spans`).
CONTINUITY_FIELDS = 4


def pieces(
    xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    cams: NDArray[np.int64],
    step_mm: float,
    tolerance_mm: float = np.inf,
) -> NDArray[np.int64]:
    """Piece label of each two-camera point: points of one camera pair (``cams`` (n, 2))
    in consecutive fields, each the nearest such point within ``step_mm`` of the last and
    continuing the last two within ``tolerance_mm`` (second difference)."""
    n = len(xyz)
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    key = cams[:, 0] * (cams.max() + 1) + cams[:, 1]
    # one tree, fields and camera pairs kept apart
    emb = embed_fields(xyz, field * (key.max() + 1) + key)
    tree = cKDTree(emb)
    nxt = embed_fields(xyz, (field + 1) * (key.max() + 1) + key)
    d, j = tree.query(nxt, distance_upper_bound=step_mm)
    ok = np.isfinite(d)
    prev = np.full(n, -1)
    prev[j[ok]] = np.flatnonzero(ok)
    # a link that breaks the piece's motion (a jump the field before did not make) cuts it
    i = np.flatnonzero(ok & (prev >= 0))
    jump = np.linalg.norm(xyz[j[i]] - 2 * xyz[i] + xyz[prev[i]], axis=1) > tolerance_mm
    after = np.zeros(n, dtype=bool)
    after[i[jump]] = True
    ok[i[jump & ~after[prev[i]]]] = False  # the field after a jump is judged across it
    graph = coo_matrix((np.ones(int(ok.sum())), (np.flatnonzero(ok), j[ok])), shape=(n, n))
    return connected_components(graph, directed=False)[1]


def predictions(
    xyz: NDArray[np.float64], field: NDArray[np.int64], step_mm: float, side: int
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Constant-velocity predictions of every point one field on (``side`` +1) or back
    (-1): ``2 q - r`` with ``r`` the nearest point of the field before ``q`` (after, going
    back) within ``step_mm``; ``q`` itself without one. Returns the predictions and their
    fields."""
    ok = np.flatnonzero(np.all(np.isfinite(xyz), axis=1))
    tree = cKDTree(embed_fields(xyz[ok], field[ok]))
    d, j = tree.query(embed_fields(xyz[ok], field[ok] - side), distance_upper_bound=step_mm)
    prev = np.where(np.isfinite(d)[:, None], xyz[ok][np.minimum(j, len(ok) - 1)], xyz[ok])
    return 2.0 * xyz[ok] - prev, field[ok] + side


def claimed_pieces(
    a: NDArray[np.int64],
    b: NDArray[np.int64],
    xyz: NDArray[np.float64],
    known_xyz: NDArray[np.float64],
    known_field: NDArray[np.int64],
    table: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]],
    dlts: NDArray[np.float64],
    params: ReconParams,
    rivals: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]] | None = None,
    carry_fields: int = 0,
    coast_fields: int = 0,
) -> NDArray[np.bool_]:
    """Which two-camera points lie on pieces whose rays other trajectories claim.

    A piece is judged at the ends of its smooth runs, where its motion jumps as well as
    where it begins and ends: a crossing that by nearness alone continues a marker's own
    piece begins at such a jump (modern 3 cameras seed 365: a crossing on an iliac
    spine's camera-2 ray, 92 mm from it for 46 fields, glued to that marker's piece).
    A ray (blob) is claimed at a run's first (last) field when a trajectory absent
    from that field (no point, known or two-camera, within the tolerance of its
    prediction from the two fields before (after)) predicts a position within the
    tolerance of the ray and farther than that from the piece's point. A piece is
    withdrawn (as far as its motion runs smoothly from the claimed end: a ghost whose
    blob a marker's own pair takes back next field, 200 mm on, modern 3 cameras seed
    332, is one piece with the marker by nearness alone) when its two rays are claimed
    by two different trajectories at either end: one trajectory near both rays is the
    point's own, predicted a little off. (One claimed ray was tried as enough: it
    withdrew true pieces wherever a marker's ray passes another's prediction, and cost
    up to 13 points of recall.) One claimed
    ray is enough when the claim comes with the ray's own pair: a candidate pair
    (``rivals``) of that field shares the blob with the piece's point, lies farther than
    the tolerance from it and within half the tolerance of the prediction of a
    trajectory that outlasts the piece (a known marker, or a longer smooth run) and predicts
    farther than twice the tolerance from the piece's point. The piece then holds the
    blob that a marker's trajectory, continued into the piece's fields, needs: one
    marker's ray crossed with a single-view marker's ray, the blob's true pair left out.
    Trajectories lost up to ``carry_fields`` fields before the piece's first field (after
    its last) claim rays too, from where their rigid companions carry them
    (:func:`~kisscal.recon.carried.carried`), where no point lies: less exact than a
    prediction over one field, such a claim counts only farther than twice the tolerance
    from the piece's point, and only where the same trajectory, carried one field into the
    run, lies on the ray there too: a ghost's ray stays with its marker, while a carried
    position tens of millimetres off crosses a true marker's ray by chance, for a field
    (modern 3 cameras seed 325: LHEE and RHEE carried 46 and 15 fields, 48 and 60 mm off,
    lay on RTIB's two rays at the last field of its 164-field piece).

    Parameters
    ----------
    a, b : ndarray of int, shape (n,)
        The two blobs (rows of ``table``) of each two-camera point; ``xyz`` (n, 3) the
        points.
    known_xyz, known_field : ndarray
        The markers that three or more cameras see.
    table : tuple of ndarray
        The trial's 2D table: field, camera and uv (linearised px) of each blob.
    dlts : ndarray, shape (n_cameras, 11)
    params : ReconParams
        ``two_camera_step_mm`` (the reach of a piece from one field to the next) and
        ``two_camera_continuity_mm`` (the tolerance).
    rivals : tuple of ndarray, optional
        All candidate pairs: blobs ``a``, ``b`` (n_candidates,) and points (n_candidates, 3).
    carry_fields : int
        Fields a lost trajectory is carried (``params.two_camera_carry_s`` at the field
        rate); 0 carries none. Those with no companion coast ``coast_fields`` on their
        own velocity (:func:`~kisscal.recon.carried.coasted`).

    Returns
    -------
    ndarray of bool, shape (n,)
        Points of withdrawn pieces.

    References
    ----------
    Küçük, M. (2005). 3D reconstruction and tracking of markers (thesis), 3.4: the
    constant-velocity prediction gate.
    """
    step_mm, tolerance_mm = params.two_camera_step_mm, params.two_camera_continuity_mm
    t_field, camera, uv = table
    field = t_field[a]
    out = np.zeros(len(a), dtype=bool)
    if len(a) == 0:
        return out
    cams = np.column_stack([camera[a], camera[b]])
    label = pieces(xyz, field, cams, step_mm)
    # what is withdrawn: the claimed end's run up to where the piece's motion jumps
    smooth = pieces(xyz, field, cams, step_mm, tolerance_mm)
    all_xyz = np.concatenate([known_xyz, xyz])
    all_field = np.concatenate([known_field, field])
    ok = np.all(np.isfinite(all_xyz), axis=1)
    here = cKDTree(embed_fields(all_xyz[ok], all_field[ok]))
    flagged = np.zeros(smooth.max() + 1, dtype=bool)
    # how many fields each trajectory holds: a known marker outlasts every piece
    span = np.r_[
        _known_spans(known_xyz, known_field, step_mm, tolerance_mm), np.bincount(label)[label]
    ]
    chains = links(all_xyz[ok], all_field[ok], step_mm, tolerance_mm)
    trajectories = all_xyz[ok], all_field[ok], span[ok], chains
    smooth_span = np.r_[span[: len(known_xyz)], np.bincount(smooth)[smooth]]
    judged = []
    for side in (1, -1):  # the first field of a run (from the field before), the last
        ends = _piece_ends(smooth, field, side)
        pred, p_field = predictions(all_xyz, all_field, step_mm, side)
        gone = here.query(embed_fields(pred, p_field))[0] > tolerance_mm
        src = np.flatnonzero(ok)[gone]
        if len(ends) == 0:
            continue
        # the trajectories absent from the field: their predictions, fields and spans
        claimers = pred[gone], p_field[gone], span[src]
        point = (xyz[ends], field[ends], np.bincount(label)[label[ends]])
        carry = carry_fields, coast_fields
        *lost, lost_end = _carried_claimers(*trajectories, here, params, side, *carry)
        margin = np.r_[np.full(len(src), tolerance_mm), np.full(len(lost[0]), 2 * tolerance_mm)]
        both = (*(np.concatenate([c, m]) for c, m in zip(claimers, lost, strict=True)), margin)
        hits, stolen = [], np.zeros(len(ends), dtype=bool)
        source = np.r_[src, np.flatnonzero(ok)[lost_end]]
        inner = _inward(smooth, field, ends, side)
        has = inner >= 0
        at = point, (xyz[inner[has]], field[inner[has]], point[2][has])
        for blob in (a, b):  # each ray of the piece's end, against the claimers
            rays = blob[ends], blob[inner[has]], has
            hits.append(
                _lasting(rays, at, both, (camera, uv), dlts, tolerance_mm, source, len(src))
            )
            if rivals is not None:  # judged by smooth runs: nearness glues a ghost's
                # crossing to other pieces (lowcost seed 427: a 168-field piece by
                # nearness whose run onto RTOE's camera-1 ray was a few fields)
                runs = pred[gone], p_field[gone], smooth_span[src]
                stolen |= _rival_claims(blob[ends], point, rivals, runs, tolerance_mm)
        flagged[smooth[ends[stolen]]] = True
        judged.append((ends, *hits, source, point[2]))
    # a ghost's own trajectory claims nothing: a piece withdrawn here does not claim a
    # longer one (modern 3 cameras seed 429: a 4-field crossing on the ankle's camera-1
    # ray, predicted back 32 mm off it, withdrew the ankle's 380-field piece with it)
    ghost = np.zeros(len(all_xyz), dtype=bool)
    # the trajectory of each claim's source: a two-camera piece is one, whichever of its
    # points predicts or ends a chain (kiss 3 cameras seed 444: a 14-field ghost's
    # prediction back from its first field and its position carried back from its second,
    # where its chain of links begins, fell on the two rays of marker 1's 85-field piece
    # and withdrew it as if two trajectories claimed them)
    whose = np.r_[np.arange(len(known_xyz)), len(known_xyz) + label]
    for _ in range(2):  # all claims, then without those of withdrawn pieces
        withdrawn = flagged.copy()
        for ends, hit_a, hit_b, source, length in judged:
            by = np.where(hit_a >= 0, source[hit_a], -1), np.where(hit_b >= 0, source[hit_b], -1)
            ha, hb = ((h >= 0) & ~(ghost[h] & (span[h] < length[:, None])) for h in by)
            wa, wb = (np.where(h >= 0, whose[h], -1) for h in by)
            # two different trajectories, one on each ray (one near both is the point's own)
            claimed = np.any(
                ha[:, :, None] & hb[:, None, :] & (wa[:, :, None] != wb[:, None, :]), axis=(1, 2)
            )
            withdrawn[smooth[ends[claimed]]] = True
        ghost[len(known_xyz) :] = withdrawn[smooth]
    out[withdrawn[smooth]] = True
    return out


def _known_spans(
    xyz: NDArray[np.float64], field: NDArray[np.int64], step_mm: float, tolerance_mm: float
) -> NDArray[np.float64]:
    """Fields each known marker's run holds: infinite (it outlasts every piece) from the
    four fields of a continuity window on; three rays of three markers that cross for a
    field or two make a shorter one (lowcost seed 433: LKNE's camera 0, RKNE's camera 1
    and LTIB's camera 2 for 2 fields, whose crossing withdrew LTIB's and LKNE's pieces)."""
    out = np.full(len(xyz), np.inf)
    ok = np.flatnonzero(np.all(np.isfinite(xyz), axis=1))
    run = pieces(xyz[ok], field[ok], np.zeros((len(ok), 2), dtype=np.int64), step_mm, tolerance_mm)
    count = np.bincount(run)[run]
    out[ok] = np.where(count >= CONTINUITY_FIELDS, np.inf, count)
    return out


def _carried_claimers(
    xyz: NDArray[np.float64],
    field: NDArray[np.int64],
    span: NDArray[np.float64],
    chains: tuple[NDArray[np.int64], NDArray[np.int64]],
    here: cKDTree,
    params: ReconParams,
    side: int,
    fields: int,
    coast: int,
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64], NDArray[np.int64]]:
    """The trajectories lost a few fields before (after) a field, carried into it by a
    marker of their rigid body (:func:`~kisscal.recon.carried.carried`), where no point
    lies within the tolerance: their positions, fields, spans and ends (rows of ``xyz``)."""
    tolerance_mm = params.two_camera_continuity_mm
    step_mm = params.two_camera_step_mm
    pos, p_field, end = carried(xyz, field, chains, step_mm, tolerance_mm, side, fields, coast)
    gone = here.query(embed_fields(pos, p_field))[0] > tolerance_mm
    return pos[gone], p_field[gone], span[end[gone]], end[gone]


def _lasting(
    rays: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]],
    at: tuple[tuple, tuple],
    claimers: tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64], NDArray],
    image: tuple[NDArray[np.int64], NDArray[np.float64]],
    dlts: NDArray[np.float64],
    tolerance_mm: float,
    source: NDArray[np.int64],
    n_predicted: int,
) -> NDArray[np.int64]:
    """:func:`_claims` on the blobs of runs' ends (``rays``: the end's blob, the blob one
    field inward where ``has``; ``at``: the points there), a carried claim (claimer index
    ``n_predicted`` on) kept only where the same trajectory (``source`` of each claimer)
    claims the inward blob's ray too: a carried position is a companion's displacement
    over many fields, and one that crosses a marker's ray by chance leaves it a field on."""
    end, inward, has = rays
    hit = _claims(end, at[0], claimers, image, dlts, tolerance_mm)
    hit_in = _claims(inward, at[1], claimers, image, dlts, tolerance_mm)
    by, by_in = np.full(hit.shape, -1), np.full(hit_in.shape, -1)
    by[hit >= 0] = source[hit[hit >= 0]]
    by_in[hit_in >= 0] = source[hit_in[hit_in >= 0]]
    was = np.full((len(end), hit_in.shape[1]), -1)
    was[has] = by_in
    loose = (hit >= n_predicted) & has[:, None]
    held = np.any((by[:, :, None] == was[:, None, :]) & (by[:, :, None] >= 0), axis=2)
    return np.where(loose & ~held, -1, hit)


def _inward(
    label: NDArray[np.int64], field: NDArray[np.int64], ends: NDArray[np.int64], side: int
) -> NDArray[np.int64]:
    """Index of the point of each end's run (``label``) one field inward (``side`` +1: the
    run's first point, the next field), -1 for a run of one field."""
    span = int(field.max()) + 2
    key = label * span + field
    order = np.argsort(key, kind="stable")
    want = label[ends] * span + field[ends] + side
    at = np.minimum(np.searchsorted(key[order], want), len(order) - 1)
    return np.where(key[order][at] == want, order[at], -1)


def _piece_ends(label: NDArray[np.int64], field: NDArray[np.int64], side: int) -> NDArray[np.int64]:
    """Index of each piece's first point (``side`` +1) or last (-1)."""
    order = np.lexsort((side * field, label))
    first = np.r_[True, label[order][1:] != label[order][:-1]]
    return order[first]


def _claims(
    blob: NDArray[np.int64],
    point: tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]],
    claimers: tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]],
    image: tuple[NDArray[np.int64], NDArray[np.float64]],
    dlts: NDArray[np.float64],
    tolerance_mm: float,
) -> NDArray[np.int64]:
    """Per blob (of a piece's end: ``point`` its point, field and piece length), the
    claimers' predictions of its field (``claimers``: predictions, fields, spans; index,
    up to three; -1 none) within ``tolerance_mm`` of the blob's ray (``image``: camera
    and uv of every blob) and farther than that from the point."""
    point, p_field = point[0], point[1]
    pred, pred_field = claimers[0], claimers[1]
    camera, uv = image
    k = 3  # a prediction per nearby trajectory
    out = np.full((len(blob), k), -1, dtype=np.int64)
    for c in np.unique(camera[blob]):
        rows = np.flatnonzero(camera[blob] == c)
        proj = project_rows(dlts, np.full(len(pred), c), pred)
        fine = np.all(np.isfinite(proj), axis=1)
        if not fine.any():
            continue
        tree = cKDTree(embed_fields(proj[fine], pred_field[fine]))
        kk = min(k, int(fine.sum()))
        _, j = tree.query(embed_fields(uv[blob[rows]], p_field[rows]), k=kk)
        j = j.reshape(len(rows), kk)
        cand = np.flatnonzero(fine)[np.minimum(j, int(fine.sum()) - 1)]
        same = pred_field[cand] == p_field[rows][:, None]
        q = pred[cand].reshape(-1, 3)
        size = pixel_size_mm(dlts, np.full(len(q), c), q).reshape(cand.shape)
        across = np.linalg.norm(proj[cand] - uv[blob[rows]][:, None], axis=2) * size
        far = np.linalg.norm(pred[cand] - point[rows][:, None], axis=2) > claimers[3][cand]
        hit = same & (across <= tolerance_mm) & far
        out[rows, :kk] = np.where(hit, cand, -1)
    return out


def _rival_claims(
    mine: NDArray[np.int64],
    point: tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]],
    rivals: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64]],
    claimers: tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.float64]],
    tolerance_mm: float,
) -> NDArray[np.bool_]:
    """Per piece end (``mine``: one of its blobs; ``point``: its point, field and piece
    length), whether a rival candidate pair (``rivals``: blobs a, b, point) shares the
    blob, lies farther than ``tolerance_mm`` from the point and within half of it of a
    claimer's prediction (``claimers``: predictions, fields, spans) whose trajectory
    outlasts the piece and predicts farther than twice ``tolerance_mm`` from the point."""
    xyz, field, length = point
    pred, pred_field, held = claimers
    ra, rb, r_xyz = rivals
    out = np.zeros(len(mine), dtype=bool)
    ok = np.all(np.isfinite(r_xyz), axis=1)
    if len(pred) == 0 or not ok.any():
        return out
    # rival index by blob: each candidate under both its blobs
    blob = np.concatenate([ra[ok], rb[ok]])
    cand = np.concatenate([np.flatnonzero(ok)] * 2)
    order = np.argsort(blob, kind="stable")
    blob, cand = blob[order], cand[order]
    lo, hi = np.searchsorted(blob, mine), np.searchsorted(blob, mine, side="right")
    n = hi - lo
    end_of = np.repeat(np.arange(len(mine)), n)
    rival = cand[np.repeat(lo - np.cumsum(np.r_[0, n[:-1]]), n) + np.arange(n.sum())]
    away = np.linalg.norm(r_xyz[rival] - xyz[end_of], axis=1) > tolerance_mm
    end_of, rival = end_of[away], rival[away]
    if len(rival) == 0:
        return out
    tree = cKDTree(embed_fields(pred, pred_field))
    d, j = tree.query(embed_fields(r_xyz[rival], field[end_of]))
    # the rival on the prediction (within half the tolerance: a rival through a blob
    # that two markers' images share lies off by the other marker's share), and the
    # claimer another marker's trajectory (the piece's own, predicted a tolerance
    # off with its point a tolerance off the other way, claims nothing)
    hit = np.flatnonzero(d <= tolerance_mm / 2)
    other = np.linalg.norm(pred[j[hit]] - xyz[end_of[hit]], axis=1) > 2 * tolerance_mm
    hit = hit[other & (held[j[hit]] > length[end_of[hit]])]
    out[end_of[hit]] = True
    return out
