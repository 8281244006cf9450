"""A whole trial from linearised 2D blobs to 3D points: filter, match, triangulate."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.errors import InputError
from kisscal.recon.apart import deblend_apart
from kisscal.recon.assign import check_table
from kisscal.recon.body import RigidTriangles
from kisscal.recon.deblend import (
    Deblended,
    MergeScene,
    deblend_held,
    deblend_merged,
    deblend_pairs,
)
from kisscal.recon.ends import extend_ends
from kisscal.recon.group import Solved, residual_limit_px, triangulate_markers
from kisscal.recon.hidden import deblend_hidden
from kisscal.recon.match import match_trial
from kisscal.recon.params import DEFAULT_PARAMS, ReconParams
from kisscal.recon.seeded import deblend_seeded
from kisscal.recon.stationary import false_detections
from kisscal.recon.unmerged import (
    deblended_in,
    merged_pairs,
    predicted_beside,
    predicted_pairs,
    pulled_pairs,
    shared_blobs,
)


@dataclass(frozen=True)
class Points3D:
    """3D points of a trial, one per reconstructed marker per field.

    Attributes
    ----------
    field : ndarray of int, shape (n_points,)
        Field index of each point (ascending).
    xyz_mm : ndarray, shape (n_points, 3)
        Lab coordinates (mm).
    n_cameras : ndarray of int, shape (n_points,)
        Cameras whose blobs formed the point.
    rms_px : ndarray, shape (n_points,)
        Reprojection RMS over those blobs, ``sqrt(mean(du^2 + dv^2))`` (px).
    blob_row : ndarray of int, shape (n_points, n_cameras_total)
        For each camera, the row of the input 2D table that the point used, -1 if none.
    marker : ndarray of int, shape (n_blobs,)
        For each input row, the point (row of this table) it ended in, -1 if unmatched.
    stationary : ndarray of bool, shape (n_blobs,)
        Input rows removed as stationary false detections.
    stationary_test : str
        How they were judged (:func:`kisscal.recon.stationary.false_detections`):
        ``"motion"``, ``"short"`` (a trial too short or too still to judge by motion: none
        removed) or ``"off"``.
    """

    field: NDArray[np.int64]
    xyz_mm: NDArray[np.float64]
    n_cameras: NDArray[np.int64]
    rms_px: NDArray[np.float64]
    blob_row: NDArray[np.int64]
    marker: NDArray[np.int64]
    stationary: NDArray[np.bool_]
    stationary_test: str = "motion"

    def __len__(self) -> int:
        return len(self.field)

    def summary(
        self, n_fields: int | None = None, params: ReconParams = DEFAULT_PARAMS
    ) -> dict[str, Any]:
        """Counts, residuals, coverage and warnings for ``recon.json`` / ``summary.json``.

        Parameters
        ----------
        n_fields : int, optional
            Fields of the trial (blank fields included); default: up to the last point.
        params : ReconParams
            ``min_coverage`` and ``max_unmatched_fraction`` say when coverage is poor.

        Returns
        -------
        dict
            ``points``, ``fields``, ``fields_with_points``, ``blobs``, ``blobs_used``,
            ``blobs_stationary``, ``blobs_unmatched``, ``rms_px_median``, ``rms_px_max``,
            ``points_by_n_cameras`` (index = number of cameras), ``stationary_test``;
            ``markers_per_field`` (the trial's full count: the 90th percentile of points
            per field), ``fields_with_all_markers``, ``coverage`` (points / (markers per
            field x fields)), ``blobs_unmatched_fraction`` (of the blobs left after the
            stationary filter) and ``warnings`` (one line each, with the numbers).

        Examples
        --------
        >>> import numpy as np
        >>> e = np.zeros(0, dtype=int)
        >>> empty = Points3D(e, np.zeros((0, 3)), e, np.zeros(0), e.reshape(0, 2), e, e > 0)
        >>> empty.summary(n_fields=3)["warnings"]
        ['no 3D points in 3 fields (0 blobs)']
        """
        used = int((self.marker >= 0).sum())
        still = int(self.stationary.sum())
        rms = self.rms_px[np.isfinite(self.rms_px)]
        n_fields = int(self.field.max(initial=-1)) + 1 if n_fields is None else n_fields
        per_field = np.bincount(self.field, minlength=n_fields)
        full = int(np.quantile(per_field[per_field > 0], 0.9, method="lower")) if used else 0
        candidates = len(self.marker) - still
        out: dict[str, Any] = {
            "points": len(self),
            "fields": n_fields,
            "fields_with_points": len(np.unique(self.field)),
            "blobs": len(self.marker),
            "blobs_used": used,
            "blobs_stationary": still,
            "blobs_unmatched": candidates - used,
            "rms_px_median": float(np.median(rms)) if len(rms) else None,  # JSON null
            "rms_px_max": float(rms.max()) if len(rms) else None,
            "points_by_n_cameras": np.bincount(
                self.n_cameras, minlength=self.blob_row.shape[1] + 1
            ).tolist(),
            "stationary_test": self.stationary_test,
            "markers_per_field": full,
            "fields_with_all_markers": int((per_field >= full).sum()) if full else 0,
            "coverage": len(self) / (full * n_fields) if full and n_fields else 0.0,
            "blobs_unmatched_fraction": (candidates - used) / candidates if candidates else 0.0,
        }
        out["warnings"] = coverage_warnings(out, params)
        return out


def coverage_warnings(summary: dict[str, Any], params: ReconParams) -> list[str]:
    """One line per sign of poor coverage in a trial's :meth:`Points3D.summary`, with the
    numbers: no points; fewer points than ``params.min_coverage`` of the trial's marker
    count in every field; more than ``params.max_unmatched_fraction`` of blobs unmatched."""
    s = summary
    if s["points"] == 0:
        return [f"no 3D points in {s['fields']} fields ({s['blobs']} blobs)"]
    out = []
    if s["coverage"] < params.min_coverage:
        out.append(
            f"coverage {100 * s['coverage']:.0f} %: {s['points']} points in {s['fields']}"
            f" fields of up to {s['markers_per_field']} markers; {s['fields_with_all_markers']}"
            f" fields have them all"
        )
    if s["blobs_unmatched_fraction"] > params.max_unmatched_fraction:
        by_n = ", ".join(f"{n}: {k}" for n, k in enumerate(s["points_by_n_cameras"]) if k)
        out.append(
            f"{100 * s['blobs_unmatched_fraction']:.0f} % of blobs unmatched"
            f" ({s['blobs_unmatched']} of {s['blobs'] - s['blobs_stationary']}; points by"
            f" number of cameras {by_n}): markers seen by too few cameras, or a calibration"
            f" that does not fit the trial"
        )
    return out


def points_from_markers(
    marker: NDArray[np.int64],
    field: NDArray[np.int64],
    camera: NDArray[np.int64],
    uv: NDArray[np.float64],
    dlts: NDArray[np.float64],
    reweight_iterations: int,
    stationary: NDArray[np.bool_] | None = None,
    stationary_test: str = "off",
    solved: Solved | None = None,
) -> Points3D:
    """Triangulate every marker (ids 0..m-1 in field order) from all its blobs (``solved``:
    markers of this table triangulated before, :class:`~kisscal.recon.group.Solved`)."""
    n_cam = len(dlts)
    rows = np.flatnonzero(marker >= 0)
    m = int(marker.max()) + 1 if len(rows) else 0
    tri = triangulate_markers(marker, camera, uv, dlts, reweight_iterations, solved)
    blob_row = np.full((m, n_cam), -1, dtype=np.int64)
    blob_row[marker[rows], camera[rows]] = rows
    pfield = np.zeros(m, dtype=np.int64)
    pfield[marker[rows]] = field[rows]
    if stationary is None:
        stationary = np.zeros(len(marker), dtype=bool)
    return Points3D(
        pfield,
        tri.xyz_mm,
        tri.n_cameras[:m].astype(np.int64),
        tri.rms_px,
        blob_row,
        marker,
        stationary,
        stationary_test,
    )


def reconstruct_trial(
    field: ArrayLike,
    camera: ArrayLike,
    uv: ArrayLike,
    dlts: ArrayLike,
    params: ReconParams = DEFAULT_PARAMS,
    rate_hz: float = 50.0,
    body: RigidTriangles | None = None,
) -> Points3D:
    """Reconstruct the 3D points of a trial from its linearised 2D blobs.

    Steps: stationary false detections removed per camera over the whole trial (Küçük 2005,
    3.3.1; if ``params.stationary_filter`` and the trial is long enough and moves), blobs
    matched across cameras with ``params.strategy`` (3.3.4-3.3.5 or Shafiq et al. 2001,
    4.1) and then in pairs (:mod:`kisscal.recon.pairs`), 3D point groups united (3.3.7),
    each marker triangulated from all its blobs by least squares (Shafiq eq. 10) plus
    reweighted steps (Woltring & Huiskes 1990), markers over the trial's residual limit
    split or dropped, and the blobs this frees matched once more; points at a camera (its
    LED ring seen by the others) dropped. On small rigs (:func:`deblends`), two-camera points
    made of two merged blobs are replaced by deblended ones (:func:`unmerged`), then merged
    blobs are deblended (:mod:`kisscal.recon.deblend`, :mod:`~kisscal.recon.hidden` with
    the pairs at lost trajectories' predictions set aside (:func:`hidden_over_pairs`),
    :mod:`~kisscal.recon.seeded`, :mod:`~kisscal.recon.ends`).

    Parameters
    ----------
    field, camera : array_like of int, shape (n,)
        Field and camera index (row of ``dlts``) of each blob.
    uv : array_like, shape (n, 2)
        Linearised pixel coordinates of each blob.
    dlts : array_like, shape (n_cameras, 11)
        DLT parameters mapping lab mm to linearised px.
    params : ReconParams
    rate_hz : float
        Field rate (Hz), to judge whether the trial is long enough for the stationary
        filter, and how many fields a lost marker is carried by its rigid companion
        (``params.two_camera_carry_s``; the KISS cameras' 50 Hz by default).
    body : RigidTriangles, optional
        The trial's marker set as rigid triangles
        (:meth:`~kisscal.recon.body.RigidTriangles.from_marker_set`): two-camera pairs too
        short to continue a trajectory are taken when they keep a segment's distances
        to known points (:mod:`kisscal.recon.body`).

    Returns
    -------
    Points3D
    """
    dlts = np.asarray(dlts, dtype=float)
    if dlts.ndim != 2 or dlts.shape[1] != 11 or len(dlts) < 2:
        raise InputError(f"reconstruction needs >= 2 cameras' DLT (n, 11), got {dlts.shape}")
    if not np.all(np.isfinite(dlts)):
        bad = sorted({int(k) for k in np.nonzero(~np.isfinite(dlts))[0]})
        raise InputError(f"reconstruction: DLT parameters of camera index {bad} are not finite")
    field, camera, uv = check_table(field, camera, uv, len(dlts))
    still, test = false_detections(field, camera, uv, params, rate_hz)
    keep = np.flatnonzero(~still)
    marker = np.full(len(field), -1, dtype=np.int64)
    solved = Solved()
    kept = field[keep], camera[keep], uv[keep]
    marker[keep] = match_trial(*kept, dlts, params, solved, body, rate_hz)
    pts = points_from_markers(
        marker,
        field,
        camera,
        uv,
        dlts,
        params.reweight_iterations,
        still,
        test,
        solved.expanded(keep, len(field)),
    )
    if deblends(params, len(dlts)) and len(pts):
        limit = residual_limit_px(pts.rms_px, params)
        scene = MergeScene(field, camera, uv, ~still, dlts, params, limit)
        pts = unmerged(pts, scene)
        two = deblend_pairs(scene, pts.marker, pts.field, pts.xyz_mm)
        pts = _with_points(pts, two, camera)
        if params.deblend_held and body is not None:
            pts = _held(pts, scene, body)
        for _ in range(_DEBLEND_PASSES):  # a point found may reveal the next hidden one
            new = deblend_merged(scene, pts.marker, pts.field, pts.xyz_mm)
            if len(new.field) == 0:
                break
            pts = _with_points(pts, new, camera)
        if params.deblend_hidden and body is not None:
            pts = hidden_over_pairs(pts, scene, body)
            seeded = _seeded(pts, scene, body)  # no trajectory to predict from: last
            if seeded is not pts:  # and the trajectories they start carried on
                pts = _hidden(seeded, scene, body)
            pts = _ends(pts, scene)
        pulled = pulled_pairs(scene, pts.field, pts.xyz_mm, pts.blob_row, pts.rms_px)
        pts = _without(pts, pulled)
    return pts


def _without(pts: Points3D, drop: NDArray[np.bool_]) -> Points3D:
    """``pts`` without the points ``drop`` marks, their blobs free again."""
    if not drop.any():
        return pts
    index = np.cumsum(~drop) - 1
    held = pts.marker >= 0
    keep = held & ~drop[np.maximum(pts.marker, 0)]
    marker = np.where(keep, index[np.maximum(pts.marker, 0)], -1)
    k = ~drop
    return replace(
        pts,
        field=pts.field[k],
        xyz_mm=pts.xyz_mm[k],
        n_cameras=pts.n_cameras[k],
        rms_px=pts.rms_px[k],
        blob_row=pts.blob_row[k],
        marker=marker,
    )


def unmerged(pts: Points3D, scene: MergeScene) -> Points3D:
    """``pts`` with the two-camera points that hold a merged blob
    (:func:`~kisscal.recon.unmerged.merged_pairs`) replaced by what
    :func:`~kisscal.recon.deblend.deblend_merged` makes of their fields' free blobs
    (:func:`_replaced`); a pair none of whose blobs a new point deblends stays (it may
    be right: partners' images on the marker's own, or hidden there)."""
    drop = merged_pairs(scene, pts.field, pts.xyz_mm, pts.blob_row)
    if not drop.any():
        return pts
    rest, new = _replaced(pts, drop, scene)
    found = deblended_in(pts.blob_row, np.r_[new.merged_row, new.own_row])
    if not np.all(found[drop]):
        # the others back as they were: no new point holds their blobs; deblending again
        # without them would meet their pulled points in the next fields and refuse the
        # rest (continuity)
        drop &= found
        if not drop.any():
            return pts
        rest = _without(pts, drop)
    return _with_points(rest, new, scene.camera) if len(new.field) else rest


def _replaced(
    pts: Points3D, drop: NDArray[np.bool_], scene: MergeScene
) -> tuple[Points3D, Deblended]:
    """``pts`` without the points ``drop`` marks, and the deblended points of their fields
    whose own blob is no merged one (:func:`~kisscal.recon.unmerged.shared_blobs`) nor
    beside another trajectory's prediction (:func:`~kisscal.recon.unmerged.
    predicted_beside`: a marker with no point there yet, lowcost seed 303 field 391) and,
    if a dropped pair's clean blob, fits with a residual smaller than the pair's by more
    than the trial's median one, the pair's an outlier (``merged_pair_rms_factor`` times
    that median): else the new point rests on the merge alone, the other marker perhaps
    hidden there (lowcost seed 307's toe, its pair's residual 0.00-0.02 px, went 26-31 mm
    off)."""
    fields = pts.field[drop]
    shared = shared_blobs(scene, pts.field, pts.xyz_mm, pts.blob_row)
    pair_rms = np.full(len(scene.field), np.inf)
    rows = pts.blob_row[drop]
    pair_rms[rows[rows >= 0]] = np.repeat(pts.rms_px[drop], (rows >= 0).sum(axis=1))
    rest = _without(pts, drop)
    # only the fields of the dropped points: elsewhere every step sees what it saw before
    there = replace(scene, usable=scene.usable & np.isin(scene.field, fields))
    new = deblend_merged(there, rest.marker, rest.field, rest.xyz_mm)
    typical = float(np.median(pts.rms_px))  # a marker's residual: differences below it are noise
    pair_rms[pair_rms <= scene.params.merged_pair_rms_factor * typical] = 0.0
    own = ~shared[new.own_row] & (new.rms_px + typical < pair_rms[new.own_row])
    own &= ~predicted_beside(scene, rest.field, rest.xyz_mm, new.field, new.xyz_mm, new.own_row)
    return rest, Deblended(
        new.xyz_mm[own], new.field[own], new.rms_px[own], new.own_row[own], new.merged_row[own]
    )


def _held(pts: Points3D, scene: MergeScene, body: RigidTriangles) -> Points3D:
    """``pts`` with the two-camera points that hold a merged blob moved to their marker,
    and the other marker in it added (:func:`~kisscal.recon.deblend.deblend_held`)."""
    moved, moved_xyz, new = deblend_held(
        scene, pts.marker, pts.field, pts.xyz_mm, pts.blob_row, pts.rms_px, body
    )
    if len(moved) == 0:
        return pts
    xyz = pts.xyz_mm.copy()
    xyz[moved] = moved_xyz
    return _with_points(replace(pts, xyz_mm=xyz), new, scene.camera)


def _seeded(pts: Points3D, scene: MergeScene, body: RigidTriangles) -> Points3D:
    """``pts`` with the pairs of markers merged in one view and apart in one other that
    :func:`~kisscal.recon.seeded.deblend_seeded` places from their pair points, then those
    each seen by one other camera (:func:`~kisscal.recon.apart.deblend_apart`)."""
    for deblend in (deblend_seeded, deblend_apart):
        new = deblend(scene, pts.marker, pts.field, pts.xyz_mm, body.lengths())
        pts = _with_points(pts, new, scene.camera) if len(new.field) else pts
    return pts


def _ends(pts: Points3D, scene: MergeScene) -> Points3D:
    """``pts`` with the free pairs :func:`~kisscal.recon.ends.extend_ends` takes at the
    trajectories' ends, one field further per round."""
    for _ in range(_HIDDEN_PASSES):
        new = extend_ends(scene, pts.marker, pts.field, pts.xyz_mm)
        if len(new.field) == 0:
            break
        pts = _with_points(pts, new, scene.camera)
    return pts


def hidden_over_pairs(pts: Points3D, scene: MergeScene, body: RigidTriangles) -> Points3D:
    """:func:`_hidden` without the two-camera points whose blobs both lie beside lost
    trajectories' predictions (:func:`~kisscal.recon.unmerged.predicted_pairs`): the
    hidden markers are placed from those blobs; a pair whose blobs no point takes is put
    back as it was."""
    drop = predicted_pairs(scene, pts.field, pts.xyz_mm, pts.blob_row)
    if not drop.any():
        return _hidden(pts, scene, body)
    out = _hidden(_without(pts, drop), scene, body)
    rows = np.sort(pts.blob_row[drop], axis=1)[:, -2:]
    back = np.all(out.marker[rows] < 0, axis=1)
    if not back.any():
        return out
    k = np.flatnonzero(drop)[back]
    again = Deblended(pts.xyz_mm[k], pts.field[k], pts.rms_px[k], rows[back, 1], rows[back, 0])
    return _with_points(out, again, scene.camera)


def _hidden(pts: Points3D, scene: MergeScene, body: RigidTriangles) -> Points3D:
    """``pts`` with the markers :func:`~kisscal.recon.hidden.deblend_hidden` places, one
    field further along their trajectories per round."""
    for _ in range(_HIDDEN_PASSES):
        got = deblend_hidden(
            scene, pts.marker, pts.field, pts.xyz_mm, pts.n_cameras, body.lengths()
        )
        if len(got.new.field) == 0:
            break
        xyz = pts.xyz_mm.copy()
        xyz[got.moved] = got.moved_xyz
        pts = _with_points(replace(pts, xyz_mm=xyz), got.new, scene.camera)
    return pts


def deblends(params: ReconParams, n_cameras: int) -> bool:
    """Whether a rig of ``n_cameras`` cameras deblends merged blobs (see ``params``)."""
    return (
        params.allow_two_camera
        and params.deblend_merged
        and (n_cameras <= params.deblend_max_cameras)
    )


#: Rounds of :func:`~kisscal.recon.deblend.deblend_merged`, each with the points of the last.
_DEBLEND_PASSES = 3

#: Rounds of :func:`~kisscal.recon.hidden.deblend_hidden`, one field each way per round: a
#: blob lost for up to a second (50 fields at 50 Hz) is crossed from both ends.
_HIDDEN_PASSES = 30


def _with_points(pts: Points3D, new: Deblended, camera: NDArray[np.int64]) -> Points3D:
    """``pts`` with the deblended points added, in field order (the merged blob stays
    with its first point in ``marker``)."""
    n_old, m = len(pts), len(new.field)
    field = np.concatenate([pts.field, new.field])
    order = np.argsort(field, kind="stable")
    index = np.empty(len(order), dtype=np.int64)
    index[order] = np.arange(len(order))
    rows = np.full((m, pts.blob_row.shape[1]), -1, dtype=np.int64)
    rows[np.arange(m), camera[new.own_row]] = new.own_row
    rows[np.arange(m), camera[new.merged_row]] = new.merged_row
    marker = np.where(pts.marker >= 0, index[np.maximum(pts.marker, 0)], -1)
    marker[new.own_row] = index[n_old:]
    taken = marker[new.merged_row] < 0  # a free merged blob goes to its first new point
    marker[new.merged_row[taken][::-1]] = index[n_old:][taken][::-1]
    return Points3D(
        field[order],
        np.concatenate([pts.xyz_mm, new.xyz_mm])[order],
        np.concatenate([pts.n_cameras, np.full(m, 2, dtype=np.int64)])[order],
        np.concatenate([pts.rms_px, new.rms_px])[order],
        np.concatenate([pts.blob_row, rows])[order],
        marker,
        pts.stationary,
        pts.stationary_test,
    )
