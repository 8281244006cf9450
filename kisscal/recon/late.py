"""Two-camera pairs made late: blobs that deblending leaves free, now beside a trajectory.

Two-camera pairs are chosen (:mod:`kisscal.recon.pairs`) before merged blobs are deblended
(:mod:`kisscal.recon.deblend`, :mod:`kisscal.recon.hidden`). A marker whose image merged
with a neighbour's in one camera for a stretch has no point there, so its plain pairs
just after the stretch (both blobs its own, apart again) had no trajectory to continue
and were refused. Once deblending has placed points in the stretch, or a late pair
continues a trajectory, the pairs beside them do: this step judges the free blobs' pairs
again against all the trial's points, with the same gates (the trial's residual limit,
continuity, each blob once), and takes only pairs whose four-field window holds a point
already made: a piece of free pairs supporting only itself was judged, and refused, before.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.recon.deblend import Deblended, MergeScene, apart
from kisscal.recon.epipolar import all_fundamentals, triangulated_pairs
from kisscal.recon.group import near_cameras
from kisscal.recon.pairs import choose_pairs


def late_pairs(
    scene: MergeScene,
    marker: NDArray[np.int64],
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
) -> Deblended:
    """Two-camera points of the free blobs that continue a trajectory of the trial's
    points (see module).

    Parameters
    ----------
    scene : MergeScene
        The trial's 2D table, rig and residual limit (``params``: ``epipolar_band_px``,
        ``camera_clearance_mm``, ``group_radius_mm``, the two-camera continuity settings).
    marker : ndarray of int, shape (n,)
        Point of each blob of the 2D table (-1: free).
    p_field, p_xyz : ndarray, shapes (m,), (m, 3)
        The trial's points so far.

    Returns
    -------
    Deblended
        The new points (``own_row`` and ``merged_row``: the pair's two blobs).
    """
    field, camera, uv, usable = scene.field, scene.camera, scene.uv, scene.usable
    dlts, params, limit_px = scene.dlts, scene.params, scene.limit_px
    free = np.flatnonzero((marker < 0) & usable)
    F = all_fundamentals(dlts)
    band, reweight = params.epipolar_band_px, params.reweight_iterations
    a, b, t = triangulated_pairs(free, field, camera, uv, dlts, F, band, reweight)
    if len(a) == 0:
        return Deblended.empty()
    good = (t.rms_px <= limit_px) & ~near_cameras(t.xyz_mm, dlts, params.camera_clearance_mm)
    good[good] &= apart(t.xyz_mm[good], field[a[good]], p_xyz, p_field, params.group_radius_mm)
    a, b, xyz, rms = a[good], b[good], t.xyz_mm[good], t.rms_px[good]
    if len(a) == 0:
        return Deblended.empty()
    won = choose_pairs(a, b, xyz, field[a], p_xyz, p_field, params, True, alone=False)
    return Deblended(xyz[won], field[a[won]], rms[won], a[won], b[won])
