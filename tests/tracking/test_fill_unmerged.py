"""Single-camera fill through a blob merged with a known neighbour's image
(kisscal.tracking.fill_unmerged), against truth."""

from __future__ import annotations

import numpy as np

from kisscal.dlt.model import project_rows, ray_directions
from kisscal.tracking import TrackingParams, spare_blobs
from kisscal.tracking.fill_sphere import sphere_depth_fill
from kisscal.tracking.fill_unmerged import unmerged_depth_fill
from tests.tracking.test_bodyfill import _tracks_of, rigid_body
from tests.tracking.test_raychain import GAP, _dense
from tests.tracking.test_rayfill import _look_at

PARAMS = TrackingParams()
CAM_AT = np.array([1500.0, -1500.0, 2500.0])


def _scene(seed: int, hidden: bool = False) -> tuple:
    """Marker 3 of a rigid body seen by one camera through ``GAP`` with marker 0 (the
    only other one of its segment measured there) and a neighbour (track 4) 60 mm behind
    it along the camera's sight and 8 mm aside: their images 2.4 px apart, one blob at
    the centroid of both weighted by their areas (1 / depth², as a detector's), or the
    neighbour's image alone with ``hidden``; plus two noise blobs a field. Returns the
    truth (5, N, 3), the tracks (dense, NaN where not measured) and the spare blobs."""
    xyz = rigid_body(seed=seed, noise_mm=0.2)
    target = xyz[3, GAP].mean(axis=0)
    dlts = _look_at(target + CAM_AT, target)[None]
    sight = target - (target + CAM_AT)
    sight /= np.linalg.norm(sight)
    aside = np.cross(sight, [0.0, 0, 1])
    aside /= np.linalg.norm(aside)
    xyz = np.concatenate([xyz, (xyz[3] + 60.0 * sight + 8.0 * aside)[None]])
    fields = np.arange(GAP.start, GAP.stop)
    cam = np.zeros(fields.size, dtype=int)
    own, other = (project_rows(dlts, cam, xyz[m, GAP]) for m in (3, 4))
    depth = [np.linalg.norm(xyz[m, GAP] - (target + CAM_AT), axis=1)[:, None] for m in (3, 4)]
    merged = (own / depth[0] ** 2 + other / depth[1] ** 2) / (1 / depth[0] ** 2 + 1 / depth[1] ** 2)
    assert np.all(np.linalg.norm(own - other, axis=1) < PARAMS.ray_merge_px)
    rng = np.random.default_rng(seed)
    blob = (other if hidden else merged) + rng.normal(0, 0.05, own.shape)
    noise = rng.uniform([0, 0], [640, 480], (2 * fields.size, 2))
    f = np.r_[fields, np.repeat(fields, 2)]
    spare = spare_blobs(f, np.zeros(f.size), np.r_[blob, noise], dlts)
    dense = _dense(_tracks_of(xyz, {1: GAP, 2: GAP, 3: GAP}))
    return xyz, dense, spare


def _ray_miss(spare, xyz: np.ndarray) -> np.ndarray:
    """Distance (mm) of each gap field's truth ``xyz`` from its blob's ray."""
    rows = np.arange(GAP.stop - GAP.start)
    d = ray_directions(spare.dlts[spare.camera[rows]], spare.uv_px[rows])
    rel = xyz - spare.centres[0]
    return np.linalg.norm(rel - np.einsum("ij,ij->i", rel, d)[:, None] * d, axis=1)


def test_a_blob_merged_with_a_measured_neighbour_places_the_marker_on_its_own_ray():
    xyz, dense, spare = _scene(5)
    expected = np.where(np.isfinite(dense[:, :, 0]), 0.0, np.nan)
    assert np.median(_ray_miss(spare, xyz[3, GAP])) > 3.0  # the merged blob's ray misses it
    # the fill that takes the marker's blobs alone leaves a merged one
    assert sphere_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS) is None
    got = unmerged_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS, expected=expected)
    assert got is not None
    placed = np.isfinite(got.sd_mm)
    assert placed.sum() >= 0.8 * (GAP.stop - GAP.start)
    err = np.linalg.norm(got.xyz_mm[placed] - xyz[3, GAP][placed], axis=1)
    rms = np.sqrt(np.mean(err**2))
    assert rms < 2.0
    assert rms < 1.5 * np.sqrt(np.mean(got.sd_mm[placed] ** 2))  # honest
    assert np.all(got.sd_mm[placed] <= PARAMS.ray_depth_max_error_mm)
    assert np.allclose(spare.field[got.rows], GAP.start + np.flatnonzero(placed))


def test_a_placed_neighbour_s_error_counts_and_its_image_alone_is_not_unmerged():
    xyz, dense, spare = _scene(5)
    expected = np.where(np.isfinite(dense[:, :, 0]), 0.0, np.nan)
    as_measured = unmerged_depth_fill(
        dense, 3, GAP.start, GAP.stop, spare, PARAMS, expected=expected
    )
    # the neighbour placed by another fill, 1.5 mm off, expecting 1.5 mm
    dense[4, GAP] += [0.0, 0.0, 1.5]
    expected[4, GAP] = 1.5
    got = unmerged_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS, expected=expected)
    assert got is not None
    placed = np.isfinite(got.sd_mm)
    err = np.linalg.norm(got.xyz_mm[placed] - xyz[3, GAP][placed], axis=1)
    assert np.sqrt(np.mean(err**2)) < 1.5 * np.sqrt(np.mean(got.sd_mm[placed] ** 2))
    assert np.all(got.sd_mm[placed] > as_measured.sd_mm[placed])  # its error counted
    # its error not known: not unmerged
    expected[4, GAP] = np.nan
    assert (
        unmerged_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS, expected=expected) is None
    )
    # the marker hidden behind the neighbour: the blob is the neighbour's image alone
    xyz, dense, spare = _scene(5, hidden=True)
    expected = np.where(np.isfinite(dense[:, :, 0]), 0.0, np.nan)
    assert (
        unmerged_depth_fill(dense, 3, GAP.start, GAP.stop, spare, PARAMS, expected=expected) is None
    )
