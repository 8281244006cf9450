"""Two-camera pairs that continue a trajectory at its end, gated by its prediction.

Pairs are chosen (:mod:`kisscal.recon.pairs`) before merged blobs are deblended: a
marker whose trajectory the deblending steps make (:mod:`kisscal.recon.hidden`,
:mod:`kisscal.recon.seeded`) had none when its clean pairs beyond were judged, and those
pairs were refused for want of one (kiss 3 cameras seed 305, LHEE fields 28-30, after
its merge with LANK). Judging the free pairs again against every point made (s42's late
pairs) let a pair of two merged blobs continue a trajectory 14 mm off its marker.

Here a free pair is taken only at a trajectory's end, one field per round, and only when
it agrees with the trajectory: within ``hidden_prediction_mm`` of the constant-velocity
prediction into the field where the trajectory stops
(:func:`~kisscal.recon.hidden.predictions`), within the trial's residual limit, the only
such pair of that prediction, gated by no other prediction, sharing no blob with another
gated pair, and ``group_radius_mm`` from every point of its field. A pair in doubt is
left out rather than guessed.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from kisscal.dlt.triangulate import triangulate_observations
from kisscal.recon.deblend import Deblended, MergeScene, apart
from kisscal.recon.epipolar import all_fundamentals, candidate_pairs
from kisscal.recon.group import embed_fields, near_cameras
from kisscal.recon.hidden import predictions


def extend_ends(
    scene: MergeScene,
    marker: NDArray[np.int64],
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
) -> Deblended:
    """The free pairs that continue trajectories by one field at their ends (see module).

    Parameters
    ----------
    scene : MergeScene
        The trial's 2D table, rig and residual limit; of its ``params``:
        ``two_camera_step_mm``, ``two_camera_continuity_mm``, ``hidden_prediction_mm``,
        ``epipolar_band_px``, ``group_radius_mm``, ``camera_clearance_mm``,
        ``reweight_iterations``.
    marker : ndarray of int, shape (n,)
        Point of each blob of the 2D table (-1: unused).
    p_field, p_xyz : ndarray, shapes (m,), (m, 3)
        The trial's points so far.

    Returns
    -------
    Deblended
        The new points (``own_row``, ``merged_row``: the pair's two blobs).
    """
    params = scene.params
    pf, pxyz, stops = predictions(
        p_field, p_xyz, params.two_camera_step_mm, params.two_camera_continuity_mm
    )
    pf, pxyz = pf[stops], pxyz[stops]
    a, b, xyz, rms = _free_pairs(scene, marker, pf)
    if len(a) == 0 or len(pf) == 0:
        return Deblended.empty()
    hits = cKDTree(embed_fields(xyz, scene.field[a])).query_ball_point(
        embed_fields(pxyz, pf), params.hidden_prediction_mm
    )
    one = np.flatnonzero(np.fromiter((len(h) == 1 for h in hits), dtype=bool, count=len(hits)))
    pair = np.array([hits[i][0] for i in one], dtype=np.int64)
    # gated by two predictions, or sharing a blob with another gated pair: in doubt
    gated = np.bincount(
        np.concatenate([np.asarray(h, dtype=np.int64) for h in hits] + [pair[:0]]),
        minlength=len(a),
    )
    pair = pair[gated[pair] == 1]
    twice = np.bincount(np.r_[a[gated > 0], b[gated > 0]], minlength=len(scene.field))
    pair = pair[(twice[a[pair]] == 1) & (twice[b[pair]] == 1)]
    f = scene.field[a[pair]]
    pair = pair[apart(xyz[pair], f, p_xyz, p_field, params.group_radius_mm)]
    return Deblended(xyz[pair], scene.field[a[pair]], rms[pair], a[pair], b[pair])


def _free_pairs(
    scene: MergeScene, marker: NDArray[np.int64], fields: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Epipolar pairs of free blobs in ``fields``, their points and residuals, within
    the trial's residual limit and away from the cameras."""
    field, camera, uv, params = scene.field, scene.camera, scene.uv, scene.params
    free = np.flatnonzero((marker < 0) & scene.usable & np.isin(field, fields))
    if len(free) < 2:
        return free[:0], free[:0], np.zeros((0, 3)), np.zeros(0)
    F = all_fundamentals(scene.dlts)
    a, b, _ = candidate_pairs(field[free], camera[free], uv[free], F, params.epipolar_band_px)
    a, b = free[a], free[b]
    n = len(a)
    t = triangulate_observations(
        scene.dlts,
        np.repeat(np.arange(n), 2),
        np.column_stack([camera[a], camera[b]]).ravel(),
        np.stack([uv[a], uv[b]], axis=1).reshape(-1, 2),
        n,
        params.reweight_iterations,
    )
    ok = np.all(np.isfinite(t.xyz_mm), axis=1) & (t.rms_px <= scene.limit_px)
    ok &= ~near_cameras(np.nan_to_num(t.xyz_mm), scene.dlts, params.camera_clearance_mm)
    return a[ok], b[ok], t.xyz_mm[ok], t.rms_px[ok]
