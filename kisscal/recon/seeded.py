"""Two markers merged in one camera and seen apart in one other, with no trajectory yet.

Two markers that the same two cameras see, merged into one blob ``c`` in one of them and
apart (``a``, ``b``) in the other, are placed by :mod:`kisscal.recon.hidden` from their
trajectories' predictions. A pair merged from the start of the trial, or from where it
came into view, has no trajectory to predict from: each pair (``c``, ``a``) and
(``c``, ``b``) then makes a point pulled towards the other marker by the centroid
(5-11 mm on kiss 3 cameras seed 305, LANK and LHEE 108 mm apart along one camera's line of
sight), and the contest for blobs gives ``c`` to one of them, or, its residual over the
trial's limit, to neither.

The two pair points seed the same solution as a trajectory's predictions do: both
markers on their own rays, the area-weighted mean of their images the blob ``c``, and
their distance the rigid segment length nearest to the pair points' distance (within
``two_camera_body_mm``); each marker within ``hidden_prediction_mm`` of its pair point
(the solution corrects the centroid's pull, it does not move a marker further than
that), and the fit's RMS residual within the trial's limit. Nothing is left over to
confirm one field alone: as for :func:`~kisscal.recon.deblend.deblend_pairs`, both
points must continue trajectories through the trial's points (second differences,
:func:`~kisscal.recon.pairs.choose_pairs`) and both win their blobs, or neither is
made. The step runs after the hidden passes, for the pairs they could not reach, and
the trajectories it starts carry those passes on through the fields where another
point holds the blob. A third marker in the blob that only its camera sees is not told
apart (the fit has one equation to spare): kiss 3 cameras seed 307 field 17, both
points 7-8 mm off, the one such field in the 17 trials measured.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.dlt.model import project_rows
from kisscal.dlt.triangulate import triangulate_observations
from kisscal.recon.deblend import Deblended, MergeScene, apart, free_triples
from kisscal.recon.epipolar import all_fundamentals
from kisscal.recon.group import near_cameras
from kisscal.recon.hidden import nearest_length, solve_pair
from kisscal.recon.pairs import choose_pairs


def deblend_seeded(
    scene: MergeScene,
    marker: NDArray[np.int64],
    p_field: NDArray[np.int64],
    p_xyz: NDArray[np.float64],
    lengths_mm: NDArray[np.float64],
) -> Deblended:
    """Two markers merged in one free blob and apart in one other camera (see module).

    Parameters
    ----------
    scene : MergeScene
        The trial's 2D table, rig and residual limit; of its ``params``:
        ``epipolar_band_px``, ``two_camera_body_mm``, ``hidden_prediction_mm``,
        ``group_radius_mm``, ``camera_clearance_mm``, the two-camera continuity settings
        and ``two_camera_alone_max_cameras``.
    marker : ndarray of int, shape (n,)
        Point of each blob of the 2D table (-1: unused).
    p_field, p_xyz : ndarray, shapes (m,), (m, 3)
        The trial's points so far.
    lengths_mm : ndarray, shape (k,)
        The marker set's rigid distances (:class:`~kisscal.recon.body.RigidTriangles`).

    Returns
    -------
    Deblended
        Both markers of each triple taken, own blob ``a`` or ``b``, merged blob ``c``.
    """
    field, camera, params = scene.field, scene.camera, scene.params
    c, a, b = free_triples(scene, marker, all_fundamentals(scene.dlts))
    same = camera[a] == camera[b]  # apart in two cameras: deblend_pairs places them
    c, a, b = c[same], a[same], b[same]
    if len(c) == 0:
        return Deblended.empty()
    seed_a, seed_b = _pair_points(scene, c, a), _pair_points(scene, c, b)
    want, off = nearest_length(np.linalg.norm(seed_a - seed_b, axis=1), lengths_mm)
    ok = np.isfinite(off) & (off <= params.two_camera_body_mm)
    c, a, b, seed_a, seed_b, want = (v[ok] for v in (c, a, b, seed_a, seed_b, want))
    xa, xb, rms = solve_pair(scene, c, a, b, seed_a, seed_b, want)
    good = plausible(scene, c, (xa, xb, rms), (seed_a, seed_b), p_xyz, p_field)
    c, a, b, xa, xb, rms = (v[good] for v in (c, a, b, xa, xb, rms))
    n = len(c)
    if n == 0:
        return Deblended.empty()
    own, xyz, f2 = np.r_[a, b], np.concatenate([xa, xb]), np.r_[field[c], field[c]]
    virtual = len(field) + np.arange(2 * n)  # each half's image of c
    alone = len(scene.dlts) <= params.two_camera_alone_max_cameras
    won = choose_pairs(own, virtual, xyz, f2, p_xyz, p_field, params, True, alone)
    both = won[:n] & won[n:]
    # a blob of two triples' winning halves: neither triple holds it
    both &= np.bincount(c[both], minlength=len(field))[c] == 1
    keep = np.r_[both, both]
    return Deblended(xyz[keep], f2[keep], np.r_[rms, rms][keep], own[keep], np.r_[c, c][keep])


def _pair_points(
    scene: MergeScene, c: NDArray[np.int64], a: NDArray[np.int64]
) -> NDArray[np.float64]:
    """The two-ray points of blobs ``c`` and ``a`` (the merged blob's pull included)."""
    n = len(c)
    t = triangulate_observations(
        scene.dlts,
        np.repeat(np.arange(n), 2),
        np.column_stack([scene.camera[c], scene.camera[a]]).ravel(),
        np.stack([scene.uv[c], scene.uv[a]], axis=1).reshape(-1, 2),
        n,
        scene.params.reweight_iterations,
    )
    return t.xyz_mm


def plausible(
    scene: MergeScene,
    c: NDArray[np.int64],
    solved: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]],
    seeds: tuple[NDArray[np.float64], NDArray[np.float64]],
    p_xyz: NDArray[np.float64],
    p_field: NDArray[np.int64],
) -> NDArray[np.bool_]:
    """Solutions (``xa``, ``xb``, RMS residual) within the residual limit, each marker
    within ``hidden_prediction_mm`` of its pair point, their images in blob ``c``'s
    camera more than twice the limit apart (else the blob is one marker's and the other
    pair the crossing of a single-view marker's ray with its ray, as in
    :func:`~kisscal.recon.deblend.deblend_pairs`), apart from the cameras and from every
    point of their field by ``group_radius_mm`` (not a copy of a marker already made)."""
    xa, xb, rms = solved
    seed_a, seed_b = seeds
    field = scene.field[c]
    params = scene.params
    near = params.hidden_prediction_mm
    good = np.all(np.isfinite(xa) & np.isfinite(xb), axis=1) & (rms <= scene.limit_px)
    good &= np.linalg.norm(xa - seed_a, axis=1) <= near
    good &= np.linalg.norm(xb - seed_b, axis=1) <= near
    good &= np.linalg.norm(xa - xb, axis=1) >= params.group_radius_mm
    j = scene.camera[c]
    images = project_rows(scene.dlts, j, np.nan_to_num(xa)) - project_rows(
        scene.dlts, j, np.nan_to_num(xb)
    )
    good &= np.linalg.norm(images, axis=1) > 2.0 * scene.limit_px
    for x in (xa, xb):
        good &= ~near_cameras(np.nan_to_num(x), scene.dlts, params.camera_clearance_mm)
        good &= apart(np.nan_to_num(x), field, p_xyz, p_field, params.group_radius_mm)
    return good
