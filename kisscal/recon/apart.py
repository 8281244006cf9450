"""Two markers merged in one camera, each seen apart by one other camera alone.

Markers ``A`` and ``B`` merged into one blob ``c`` in one camera, ``A``'s own blob ``a``
in a second camera and ``B``'s own ``b`` in a third, and no trajectory yet (a trial's
start: lowcost seed 375, RANK and RHEE 1.6-2.5 px apart in camera 1 for 26 fields).
:func:`~kisscal.recon.deblend.deblend_pairs` places such a triple from the centroid
alone (its images on the epipolar lines of ``a`` and ``b``); with the images 2 px apart
that solution lies 1-11 mm off both markers, the pulled points do not continue each
other, and with no marker seen by three cameras nearby none is taken.

The unknowns are the two depths along the own rays; the equations are the centroid (two,
the area-weighted mean of the images, :mod:`kisscal.recon.deblend`) and the marker set's
rigid distance between them (one, :class:`~kisscal.recon.body.RigidTriangles`): one to
spare. From the epipolar solution the depths are fitted to all three
(:func:`~kisscal.recon.hidden.solve_pair`, twice, so that the prior holds them to the
fit and not to the ill-conditioned seed), and the fit's RMS residual, the spare equation,
must lie within the trial's limit: two unrelated rays crossing near a blob keep a rigid
length only by chance. The pairs then face the checks of
:func:`~kisscal.recon.seeded.deblend_seeded`: images apart in ``c``'s camera, points
apart from the cameras and from every point of their field, and both points continuing
trajectories (:func:`~kisscal.recon.pairs.choose_pairs`, the triples' own points
included) and winning their blobs, or neither is made.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.recon.deblend import Deblended, MergeScene, free_triples, place_two
from kisscal.recon.epipolar import all_fundamentals
from kisscal.recon.hidden import nearest_length, solve_pair
from kisscal.recon.pairs import choose_pairs
from kisscal.recon.seeded import plausible


def deblend_apart(
    scene: MergeScene,
    marker: NDArray[np.int64],
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
    lengths_mm: NDArray[np.float64],
) -> Deblended:
    """Two markers merged in one free blob, each seen by one other camera (see module).

    Parameters
    ----------
    scene : MergeScene
        The trial's 2D table, rig and residual limit; of its ``params``:
        ``epipolar_band_px``, ``deblend_radius_px``, ``two_camera_body_mm``,
        ``group_radius_mm``, ``camera_clearance_mm``, the two-camera continuity settings
        and ``two_camera_alone_max_cameras``.
    marker : ndarray of int, shape (n,)
        Point of each blob of the 2D table (-1: unused).
    p_field, p_xyz : ndarray, shapes (m,), (m, 3)
        The trial's points so far.
    lengths_mm : ndarray, shape (k,)
        The marker set's rigid distances: the two markers lie the one nearest to the
        epipolar solution's distance apart (within ``two_camera_body_mm``).

    Returns
    -------
    Deblended
        Both markers of each triple taken, own blob ``a`` or ``b``, merged blob ``c``.
    """
    field, camera, params = scene.field, scene.camera, scene.params
    F = all_fundamentals(scene.dlts)
    c, a, b = free_triples(scene, marker, F)
    two = camera[a] != camera[b]  # apart in one camera: deblend_seeded places them
    c, a, b = c[two], a[two], b[two]
    if len(c) == 0:
        return Deblended.empty()
    xa, xb, ok = place_two(c, a, b, camera, scene.uv, scene.dlts, F, params, scene.limit_px)
    want, off = nearest_length(np.linalg.norm(xa - xb, axis=1), lengths_mm)
    ok &= np.isfinite(off) & (off <= params.two_camera_body_mm)
    c, a, b, xa, xb, want = (v[ok] for v in (c, a, b, xa, xb, want))
    for _ in range(2):
        xa, xb, rms = solve_pair(scene, c, a, b, xa, xb, want)
    # the seed is off by the centroid's conditioning: the fit is judged on its own
    good = plausible(scene, c, (xa, xb, rms), (xa, xb), p_xyz, p_field)
    c, a, b, xa, xb, rms = (v[good] for v in (c, a, b, xa, xb, rms))
    n = len(c)
    if n == 0:
        return Deblended.empty()
    own, xyz, f2 = np.r_[a, b], np.concatenate([xa, xb]), np.r_[field[c], field[c]]
    virtual = len(field) + np.arange(2 * n)  # each half's image of c
    alone = len(scene.dlts) <= params.two_camera_alone_max_cameras
    won = choose_pairs(own, virtual, xyz, f2, p_xyz, p_field, params, True, alone)
    both = won[:n] & won[n:]
    both &= np.bincount(c[both], minlength=len(field))[c] == 1
    keep = np.r_[both, both]
    return Deblended(xyz[keep], f2[keep], np.r_[rms, rms][keep], own[keep], np.r_[c, c][keep])
