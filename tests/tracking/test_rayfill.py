"""Single-camera fill (kisscal.tracking.rayfill) against truth."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt.model import camera_centre_mm, dlt_from_krt, project_rows
from kisscal.errors import InputError
from kisscal.tracking import FILLED_RIGID, TrackingParams, is_filled, spare_blobs
from kisscal.tracking.bodyfill import Candidate, GapFill
from kisscal.tracking.fill_place import with_rays
from kisscal.tracking.gaps import fill_gaps_logged
from kisscal.tracking.rayfill import ray_correct
from tests.tracking.test_bodyfill import _tracks_of, rigid_body

K = np.array([[1000.0, 0, 320], [0, 1000.0, 240], [0, 0, 1]])


def _look_at(centre: np.ndarray, target: np.ndarray) -> np.ndarray:
    """DLT of a camera at ``centre`` looking at ``target`` (lab Z up)."""
    z = target - centre
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0, 1])
    x /= np.linalg.norm(x)
    r = np.stack([x, np.cross(z, x), z])
    return dlt_from_krt(K, r, -r @ centre)


def rig(target: np.ndarray) -> np.ndarray:
    """Two cameras 3 m from ``target``, 90 degrees apart."""
    return np.stack(
        [_look_at(target + [3000.0, 0, 500], target), _look_at(target + [0, 3000.0, 500], target)]
    )


def test_one_camera_ray_leaves_only_the_error_along_it():
    rng = np.random.default_rng(4)
    truth = np.array([0.0, 0, 900]) + rng.normal(0, 50, (20, 3))
    dlts = rig(truth.mean(axis=0))
    prior = truth + rng.normal(0, 6.0, truth.shape)
    uv = project_rows(dlts, np.zeros(20, dtype=int), truth)
    spare = spare_blobs(np.arange(20) + 100, np.zeros(20), uv, dlts)
    xyz, n_rays, used = ray_correct(prior, 100, 6.0, spare, TrackingParams(ray_fill_px=0.01))
    assert n_rays.tolist() == [1] * 20 and used.size == 20
    # on the ray (reprojects onto the blob) ...
    assert np.abs(project_rows(dlts, np.zeros(20, dtype=int), xyz) - uv).max() < 0.01
    # ... at the prior's depth: the error left is the prior's along the line of sight
    sight = truth - camera_centre_mm(dlts[0])
    sight /= np.linalg.norm(sight, axis=1, keepdims=True)
    along = np.abs(np.sum((prior - truth) * sight, axis=1))
    assert np.allclose(np.linalg.norm(xyz - truth, axis=1), along, atol=0.05)
    assert np.sqrt(np.mean(along**2)) < 0.8 * np.sqrt(np.mean(np.sum((prior - truth) ** 2, 1)))


def test_two_rays_triangulate_and_far_or_ambiguous_blobs_are_not_taken():
    truth = np.array([[0.0, 0, 900], [10.0, 20, 950], [0, 0, 1000]])
    dlts = rig(truth.mean(axis=0))
    prior = truth + [[8.0, -5, 4], [8.0, -5, 4], [8.0, -5, 4]]
    uv = [project_rows(dlts, [c], truth[k : k + 1])[0] for k, c in [(0, 0), (0, 1), (1, 0)]]
    # field 1: a second blob beside the right one in camera 0 (ambiguous); field 2: only
    # a blob 200 px away (beyond the gate)
    uv += [uv[2] + [1.5, 0.0], project_rows(dlts, [1], truth[2:])[0] + [200.0, 0]]
    spare = spare_blobs([0, 0, 1, 1, 2], [0, 1, 0, 0, 1], np.array(uv), dlts)
    xyz, n_rays, used = ray_correct(prior, 0, 10.0, spare, TrackingParams(ray_fill_px=0.01))
    assert n_rays.tolist() == [2, 0, 0]
    assert sorted(used.tolist()) == [0, 1]
    assert np.linalg.norm(xyz[0] - truth[0]) < 0.1  # two rays: triangulated
    assert np.allclose(xyz[1:], prior[1:], atol=1e-9)


def test_fill_gaps_with_a_camera_that_still_sees_the_marker():
    xyz = rigid_body(seed=2, noise_mm=0.3)
    # marker 3 hidden for 0.6 s, its segment partners wobbling (skin): the body's fill
    # drifts; one camera still sees it
    t = np.arange(xyz.shape[1])
    xyz[:3] += (
        4.0
        * np.sin(t / 9.0)[None, :, None]
        * np.array([[1.0, 0, 0], [0, 1, 0], [0, 0, 1]])[:, None]
    )
    tracks = _tracks_of(xyz, {3: slice(100, 160)})
    # the body's fill moved onto the ray; placing the marker on its ray by the segment's
    # lengths (raychain) is left out here, and checked against this at the end
    params = TrackingParams(ray_length_max_error_mm=1e-6)
    dlts = rig(xyz[3, 100:160].mean(axis=0))
    uv = project_rows(dlts, np.zeros(60, dtype=int), xyz[3, 100:160])
    spare = spare_blobs(np.arange(100, 160), np.zeros(60), uv, dlts)
    plain, how0 = fill_gaps_logged(tracks, params)
    rays, how1 = fill_gaps_logged(tracks, params, spare)
    miss = {}
    for name, out in (("body", plain), ("ray", rays)):
        rows = is_filled(out.status) & (out.track == 3)
        assert rows.sum() == 60
        miss[name] = out.xyz_mm[rows] - xyz[3, out.field[rows]]
    assert sum(g.ray_fields for g in how1) == 60 and not any(g.ray_fields for g in how0)
    # what is left is the body fill's error along the camera's line of sight
    sight = xyz[3, 100:160] - camera_centre_mm(dlts[0])
    sight /= np.linalg.norm(sight, axis=1, keepdims=True)
    along = np.abs(np.sum(miss["body"] * sight, axis=1))
    left = np.linalg.norm(miss["ray"], axis=1)
    assert np.sqrt(np.mean((left - along) ** 2)) < 0.3
    assert np.sqrt(np.mean(left**2)) < np.sqrt(np.mean(np.sum(miss["body"] ** 2, axis=1)))
    assert spare.free.all()  # the caller's blobs are not marked
    chain, _ = fill_gaps_logged(tracks, TrackingParams(), spare)
    rows = is_filled(chain.status) & (chain.track == 3)
    placed = chain.xyz_mm[rows] - xyz[3, chain.field[rows]]
    # about as good as the body's best fill moved onto the ray (the hinge fill about
    # markers 1 and 2 here: 3.09 mm, the chain 3.28 mm; the rigid-body fill was 3.46 mm)
    assert np.sqrt(np.mean(np.sum(placed**2, axis=1))) <= 1.1 * np.sqrt(np.mean(left**2))


def test_bad_spare_blobs_are_refused():
    with pytest.raises(InputError):
        spare_blobs([0, 1], [0], np.zeros((2, 2)), np.zeros((1, 11)))
    with pytest.raises(InputError):
        spare_blobs([0], [3], np.zeros((1, 2)), np.zeros((2, 11)))
    with pytest.raises(InputError):
        spare_blobs([0], [0], np.zeros((1, 2)), np.zeros((2, 10)))


def _drifting_fill(drift_mm: float) -> tuple[list, np.ndarray, np.ndarray]:
    """A body fill of 40 fields expecting 3 mm that drifts off the truth by up to
    ``drift_mm`` (as much along camera 0's sight as along each direction across it), a
    blob of the marker in camera 0 in every field but 15-24: (the fill moved onto the
    rays, truth, which blobs are left free)."""
    truth = np.array([0.0, 0, 900]) + np.linspace(0, 400, 40)[:, None] * [1.0, 0.2, 0]
    dlts = rig(truth.mean(axis=0))
    sight = truth - camera_centre_mm(dlts[0])
    sight /= np.linalg.norm(sight, axis=1, keepdims=True)
    side = np.cross(sight, [0.0, 0, 1])
    side /= np.linalg.norm(side, axis=1, keepdims=True)
    way = (sight + side + np.cross(sight, side)) / np.sqrt(3)
    off = way * (drift_mm * np.sin(np.linspace(0, np.pi, 40)))[:, None]
    seen = np.r_[0:15, 25:40]
    uv = project_rows(dlts, np.zeros(seen.size, dtype=int), truth[seen])
    spare = spare_blobs(seen + 200, np.zeros(seen.size), uv, dlts)
    fill = GapFill(7, 200, 40, FILLED_RIGID, 3.0, (1, 2))
    got = with_rays(Candidate(truth + off, fill, 1.5), spare, TrackingParams())
    return got, truth, spare.free


@pytest.mark.parametrize("drift_mm", [2.0, 12.0])
def test_a_fill_its_rays_move_far_is_refused(drift_mm):
    # the body's fill expected 3 mm; where the rays move it far, it was that far off:
    # the fields between the blobs keep all of it, the ones on rays the part along the
    # sight. Each run kept is within the limit of the truth, and what it expects tells
    # its error; a refused run leaves its blobs free for the fills after it
    limit = TrackingParams().max_body_fill_error_mm
    got, truth, free = _drifting_fill(drift_mm)
    for xyz, f in got:
        miss = np.linalg.norm(xyz - truth[f.first_field - 200 :][: f.n_fields], axis=1)
        rms = np.sqrt(np.mean(miss**2))
        assert f.expected_error_mm <= limit and rms <= limit
        assert rms <= 1.5 * f.expected_error_mm
    n = sum(f.n_fields for _, f in got)
    assert free.sum() == 30 - sum(f.ray_fields for _, f in got)
    assert n == {2.0: 40, 12.0: 30}[drift_mm]  # 12 mm: the ten fields between refused
