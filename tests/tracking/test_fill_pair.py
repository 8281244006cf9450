"""Two markers placed together from the one blob their images merge into
(kisscal.tracking.fill_pair), against truth."""

from __future__ import annotations

import numpy as np

from kisscal.dlt.model import project_rows
from kisscal.tracking import TrackingParams, spare_blobs
from kisscal.tracking.fill_pair import merged_pair_fill, pair_fit, path_prior
from kisscal.tracking.fill_unmerged import unmerged_depth_fill
from tests.tracking.test_bodyfill import _tracks_of, rigid_body
from tests.tracking.test_raychain import _dense
from tests.tracking.test_rayfill import _look_at

PARAMS = TrackingParams()
CAM_AT = np.array([1500.0, -1500.0, 2500.0])
#: A short gap, as where a heel and an ankle merge in the one camera that sees them.
GAP = slice(100, 112)


def _foot(seed: int, apart_mm: float = 8.0) -> tuple:
    """Marker 3 of a rigid body (its only other marker measured through ``GAP`` is 0) and
    a neighbour (track 4) 60 mm behind it along the camera's sight and ``apart_mm``
    aside, at a constant length; both hidden in ``GAP`` from all but one camera, which
    sees one blob at the centroid of their images weighted by their areas (1 / depth²)
    when they lie within ``ray_merge_px``, else each image. Returns the truth (5, N, 3),
    the tracks (dense) and the spare blobs (two noise blobs a field too)."""
    xyz = rigid_body(seed=seed, noise_mm=0.2)
    target = xyz[3, GAP].mean(axis=0)
    dlts = _look_at(target + CAM_AT, target)[None]
    sight = -CAM_AT / np.linalg.norm(CAM_AT)
    aside = np.cross(sight, [0.0, 0, 1])
    aside /= np.linalg.norm(aside)
    xyz = np.concatenate([xyz, (xyz[3] + 60.0 * sight + apart_mm * aside)[None]])
    fields = np.arange(GAP.start, GAP.stop)
    cam = np.zeros(fields.size, dtype=int)
    own, other = (project_rows(dlts, cam, xyz[m, GAP]) for m in (3, 4))
    w = [
        1.0 / np.linalg.norm(xyz[m, GAP] - (target + CAM_AT), axis=1)[:, None] ** 2 for m in (3, 4)
    ]
    merged = np.linalg.norm(own - other, axis=1) < PARAMS.ray_merge_px
    rng = np.random.default_rng(seed)
    blob = np.where(merged[:, None], (w[0] * own + w[1] * other) / (w[0] + w[1]), own)
    blobs = [blob, other[~merged], rng.uniform([0, 0], [640, 480], (2 * fields.size, 2))]
    f = np.r_[fields, fields[~merged], np.repeat(fields, 2)]
    uv = np.concatenate(blobs) + rng.normal(0, 0.05, (f.size, 2))
    spare = spare_blobs(f, np.zeros(f.size), uv, dlts)
    dense = _dense(_tracks_of(xyz, {1: GAP, 2: GAP, 3: GAP, 4: GAP}))
    return xyz, dense, spare


def test_two_markers_merged_in_the_only_camera_are_placed_from_the_blob_and_lengths():
    xyz, dense, spare = _foot(5)
    known = np.isfinite(dense[:, :, 0])
    # neither is known there, so the merged blob's share cannot be taken out
    expected = np.where(known, 0.0, np.nan)
    assert (
        unmerged_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS, None, known, expected)
        is None
    )
    got = merged_pair_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS, known)
    assert got is not None and got.partners == (4,)
    placed = np.isfinite(got.sd_mm)
    assert placed.sum() >= 0.8 * (GAP.stop - GAP.start)
    err = np.linalg.norm(got.xyz_mm[placed] - xyz[3, GAP][placed], axis=1)
    rms = np.sqrt(np.mean(err**2))
    assert rms < 1.5
    assert rms < 1.5 * np.sqrt(np.mean(got.sd_mm[placed] ** 2))  # honest
    assert np.all(got.sd_mm[placed] <= PARAMS.ray_depth_max_error_mm)
    # the blob and the lengths tell more than the path across the gap alone
    _, path_sd = path_prior(dense[3], GAP.start, GAP.stop, PARAMS)
    assert np.all(got.sd_mm[placed] < path_sd[placed])
    assert got.rows.size == 0  # the blob stays for the partner's own gap
    # the partner's gap places it as well
    other = merged_pair_fill(dense, 4, GAP.start, GAP.stop, spare, PARAMS, known)
    assert other is not None
    ok = np.isfinite(other.sd_mm)
    assert np.sqrt(np.mean(np.sum((other.xyz_mm[ok] - xyz[4, GAP][ok]) ** 2, axis=1))) < 2.0


def test_images_apart_or_a_partner_not_in_the_blob_are_refused_and_say_why():
    _, dense, spare = _foot(5, apart_mm=40.0)  # each marker's own blob, close by
    known = np.isfinite(dense[:, :, 0])
    got = pair_fit(dense, 3, 4, GAP.start, GAP.stop, spare, PARAMS, known)
    assert got.fill is None and got.reason
    _, dense, spare = _foot(5)
    got = pair_fit(dense, 3, 1, GAP.start, GAP.stop, spare, PARAMS, known)
    assert got.fill is None
