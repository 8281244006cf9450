"""A marker no track took placed on its blobs' rays by its mirror image's lengths
(kisscal.tracking.fill_absent), and the fills of its segment it helps, against truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from kisscal.dlt.model import project_rows, ray_directions
from kisscal.tracking import TrackingParams, spare_blobs
from kisscal.tracking.fill_absent import (
    _depths,
    absent_placed,
    mirror_lengths,
    mirror_tracks,
    place_absent,
)
from kisscal.tracking.fill_joint import joint_ray_fill
from kisscal.tracking.fill_joint_depth import joint_depth_fill
from kisscal.tracking.gaps import fill_gaps_logged, fill_gaps_named
from kisscal.tracking.tracks import FILLED_RIGID
from tests.tracking.test_bodyfill import _tracks_of, rigid_body
from tests.tracking.test_raychain import _dense
from tests.tracking.test_rayfill import _look_at

GAP = slice(100, 140)
PARAMS = TrackingParams()
#: Tracks: the left foot whole, the right heel, toe and tibia; the right ankle has none.
LABELS = ("LHEE", "LTOE", "LANK", "LTIB", "RHEE", "RTOE", "RTIB")


def _feet(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Right foot (heel, toe, ankle, tibia; (4, N, 3)) and the tracks' truth (7, N, 3):
    the left foot the same segment 300 mm aside half a second behind (its lengths the
    right's, its pose not)."""
    right = rigid_body(seed=seed, noise_mm=0.2)
    left = np.roll(rigid_body(seed=seed + 1, noise_mm=0.2), 50, axis=1) + [0.0, 300.0, 0.0]
    return right, np.concatenate([left, right[[0, 1, 3]]])


def _cameras(right: np.ndarray, seed: int, toe: slice) -> object:
    """Camera 0 sees the right ankle all trial, camera 1 the right toe over ``toe``;
    two noise blobs a field in each."""
    # camera 1 square to the heel-toe line: the heel's length alone fixes no depth
    target = right[2].mean(axis=0)
    toe_at = right[1, toe].mean(axis=0)
    line = np.mean(right[1, toe] - right[0, toe], axis=0)
    square = np.cross(line, [0.0, 0.0, 1.0])
    square = 2800.0 * square / np.linalg.norm(square) + [0.0, 0.0, 600.0]
    dlts = np.stack(
        [_look_at(target + [2500.0, 1500.0, 600.0], target), _look_at(toe_at + square, toe_at)]
    )
    n = right.shape[1]
    fields = np.arange(n)
    toe_f = fields[toe]
    rng = np.random.default_rng(seed)
    uv = np.r_[
        project_rows(dlts, np.zeros(n, dtype=int), right[2]),
        project_rows(dlts, np.ones(toe_f.size, dtype=int), right[1, toe]),
    ]
    noise = rng.uniform([0, 0], [640, 480], (4 * n, 2))
    f = np.r_[fields, toe_f, np.repeat(fields, 4)]
    cam = np.r_[np.zeros(n), np.ones(toe_f.size), np.tile([0, 0, 1, 1], n)]
    return spare_blobs(f, cam, np.r_[uv + rng.normal(0, 0.05, uv.shape), noise], dlts)


def test_the_mirror_image_gives_the_absent_marker_s_lengths():
    right, truth = _feet(21)
    partners, length, sd = mirror_lengths(_dense(_tracks_of(truth, {})), LABELS, "RANK", PARAMS)
    assert [LABELS[p] for p in partners] == ["RHEE", "RTOE", "RTIB"]
    true = np.linalg.norm(right[[0, 1, 3]] - right[2][None], axis=2).mean(axis=1)
    assert np.allclose(length, true, atol=1.0)
    assert np.all(sd >= PARAMS.mirror_length_sd_mm)


def test_an_ankle_no_track_took_is_placed_on_its_one_camera_s_rays():
    right, truth = _feet(22)
    dense = _dense(_tracks_of(truth, {5: GAP, 6: GAP}))
    spare = _cameras(right, 22, GAP)
    rows = absent_placed(dense, LABELS, ("RANK", "RKNE"), spare, PARAMS)[1]
    assert rows.shape == (1, *dense.shape[1:])  # RKNE has no mirror image tracked
    placed = np.isfinite(rows[0, :, 0])
    outside = np.ones(placed.size, dtype=bool)
    outside[GAP] = False
    # at least two partners measured outside the gap, only the heel in it
    assert placed[outside].mean() > 0.8 and not placed[GAP].any()
    err = np.linalg.norm(rows[0, placed] - right[2, placed], axis=1)
    assert np.sqrt(np.mean(err**2)) < 2.0 and err.max() < 5.0
    # the ankle's blobs are taken, and no other
    taken = np.flatnonzero(~spare.free)
    assert taken.size == placed.sum()
    uv = project_rows(spare.dlts, spare.camera[taken], right[2, spare.field[taken]])
    assert np.all(np.linalg.norm(uv - spare.uv_px[taken], axis=1) < 1.0)


def test_a_toe_one_camera_sees_is_placed_with_the_absent_ankle_on_another_s():
    right, truth = _feet(23)
    # toe and tibia hidden for 0.4 s: the heel alone is measured beside the toe
    tracks = _tracks_of(truth, {5: GAP, 6: GAP})

    def filled(missing: tuple[str, ...]) -> tuple[int, float]:
        out, fills = fill_gaps_logged(tracks, PARAMS, _cameras(right, 23, GAP), LABELS, (), missing)
        rows = (out.track == 5) & (out.field >= GAP.start) & (out.field < GAP.stop)
        err = np.linalg.norm(out.xyz_mm[rows] - right[1, out.field[rows]], axis=1)
        expected = np.zeros(out.field.size)
        for g in fills:
            assert all(d < len(LABELS) for d in g.donors)  # the ankle's row names no donor
            f = (out.track == g.track) & (out.field >= g.first_field)
            expected[f & (out.field < g.first_field + g.n_fields)] = g.expected_error_mm
        # within 3 mm, or the fill's own expected error where it says it is poorer
        good = err < np.maximum(3.0, expected[rows])
        return int(np.sum(good)), float(np.sqrt(np.mean(err**2))) if err.size else 0.0

    without, rms_without = filled(())
    good, rms = filled(("RANK",))
    assert good == GAP.stop - GAP.start > without  # the whole gap
    assert rms < 2.0 and rms < 0.8 * rms_without


def test_an_ankle_one_camera_sees_all_trial_becomes_its_name_s_trajectory():
    # kiss 3: a marker that one camera alone sees makes no 3D point, so no piece takes its
    # name; placed on its rays by its mirror image's lengths, it becomes a track (RKNE,
    # whose mirror is not tracked, does not)
    right, truth = _feet(25)
    tracks = _tracks_of(truth, {5: GAP, 6: GAP})
    spare = _cameras(right, 25, GAP)
    out, fills = fill_gaps_logged(tracks, PARAMS, spare, LABELS, (), ("RANK", "RKNE"))
    assert out.n_tracks == len(LABELS) + 1
    rows = out.track == len(LABELS)
    assert rows.sum() > 0.8 * (truth.shape[1] - (GAP.stop - GAP.start))
    err = np.linalg.norm(out.xyz_mm[rows] - right[2, out.field[rows]], axis=1)
    assert np.sqrt(np.mean(err**2)) < 2.0 and err.max() < 5.0
    own = [g for g in fills if g.track == len(LABELS)]
    assert sum(g.n_fields for g in own) == rows.sum()
    assert all(g.status == FILLED_RIGID and g.n_fields == g.ray_fields for g in own)
    # each run's expected error is honest: its true RMS within twice what it expects
    for g in own:
        f = np.arange(g.first_field, g.first_field + g.n_fields)
        miss = np.linalg.norm(out.xyz_mm[rows][np.isin(out.field[rows], f)] - right[2, f], axis=1)
        assert np.sqrt(np.mean(miss**2)) <= 2.0 * max(g.expected_error_mm, 0.5)


def test_the_joint_solutions_smoothed_across_the_gap_place_what_each_alone_cannot():
    right, truth = _feet(24)
    dense = _dense(_tracks_of(truth, {5: GAP, 6: GAP}))
    spare = _cameras(right, 24, GAP)
    absent = absent_placed(dense, LABELS, ("RANK",), spare, PARAMS)[1]
    # each field's solution alone too loose to keep (here: a limit below its error)
    loose = PARAMS.replace(ray_length_max_error_mm=1.0)
    assert joint_ray_fill(dense, 5, GAP.start, GAP.stop, spare, loose, absent) is None
    got = joint_depth_fill(dense, 5, GAP.start, GAP.stop, spare, loose, None, absent)
    assert got is not None and 4 in got.partners  # the heel
    assert all(p < len(LABELS) for p in got.partners)  # the ankle's row names none
    placed = np.isfinite(got.sd_mm)
    assert placed.sum() >= 0.9 * (GAP.stop - GAP.start)
    assert np.all(got.sd_mm[placed] <= PARAMS.ray_depth_max_error_mm)
    err = np.linalg.norm(got.xyz_mm[placed] - right[1, GAP][placed], axis=1)
    assert np.sqrt(np.mean(err**2)) < np.sqrt(np.mean(got.sd_mm[placed] ** 2)) + 0.5
    # without the ankle's row the heel alone fixes no depth here
    assert joint_depth_fill(dense, 5, GAP.start, GAP.stop, spare, loose) is None


@pytest.mark.parametrize("f", [0, 60, 299])  # a run's first field, inside, its last
def test_an_absent_ankle_s_field_off_its_path_is_not_placed(f: int):
    # in one field the tibia is hidden and the ankle's blob is replaced by the image of a
    # point 50 mm away on the heel-toe circle: it fits both lengths, and was placed there
    right, truth = _feet(21)
    dense = _dense(_tracks_of(truth, {}))
    dense[6, f] = np.nan
    clean = absent_placed(dense, LABELS, ("RANK",), _cameras(right, 21, GAP), PARAMS)[1][0]
    heel, toe, ankle = dense[4, f], dense[5, f], right[2, f]
    axis = (toe - heel) / np.linalg.norm(toe - heel)
    centre = heel + np.dot(ankle - heel, axis) * axis
    arm = ankle - centre
    turn = 2 * np.arcsin(25.0 / np.linalg.norm(arm))
    wrong = centre + np.cos(turn) * arm + np.sin(turn) * np.cross(axis, arm)
    spare = _cameras(right, 21, GAP)
    rows = np.flatnonzero((spare.field == f) & (spare.camera == 0))
    own = project_rows(spare.dlts, [0], ankle[None])
    row = rows[np.argmin(np.linalg.norm(spare.uv_px[rows] - own, axis=1))]
    spare.uv_px[row] = project_rows(spare.dlts, [0], wrong[None])[0]
    placed = absent_placed(dense, LABELS, ("RANK",), spare, PARAMS)[1][0]
    assert np.isnan(placed[f, 0])
    assert spare.free[row]  # the wrong blob is not taken
    # the fields placed without it stay placed, where they were
    others = np.isfinite(clean[:, 0])
    others[f] = False
    assert np.allclose(placed[others], clean[others])


def _legs(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Right shank and foot on one rigid body (heel, toe, ankle, tibia, knee, thigh;
    (6, N, 3)) and its left mirror image aside and behind, whose knee and thigh turn
    about its ankle-tibia line (45 degrees): they keep their lengths to ankle and tibia
    (and to each other) and break those to heel and toe, so the knee's partners are the
    tibia, the thigh and the ankle."""
    body = rigid_body(seed=seed)
    e1, e2 = (body[1] - body[0]) / 100.0, (body[2] - body[0]) / 80.0
    frame = np.stack([e1, e2, np.cross(e1, e2)], axis=2)  # (N, 3, 3), columns the axes
    ankle, tibia = np.array([0.0, 80, 0]), np.array([30.0, 20, 60])
    local = np.array([[-100.0, 0, 150], [-80.0, 60, 250]])  # knee, thigh
    axis = (tibia - ankle) / np.linalg.norm(tibia - ankle)
    turn = np.deg2rad(45.0) * np.sin(np.arange(body.shape[1]) / 15.0)

    def placed(xyz: np.ndarray) -> np.ndarray:  # body coordinates (N, 3) to the lab
        return body[0] + np.einsum("nij,nj->ni", frame, xyz)

    right = np.concatenate([body, [placed(np.tile(p, (body.shape[1], 1))) for p in local]])
    turned = [
        placed(ankle + Rotation.from_rotvec(turn[:, None] * axis).apply(p - ankle)) for p in local
    ]
    left = np.roll(np.concatenate([body, turned]), 50, axis=1) + [0.0, 300.0, 0.0]
    rng = np.random.default_rng(seed)
    return right + rng.normal(0, 0.2, right.shape), left + rng.normal(0, 0.2, left.shape)


def test_a_knee_its_thigh_places_in_a_few_fields_waits_for_the_ankle_placed_after_it():
    # kiss 3 seed 321: the left knee, seen by one camera all trial, was placed by tibia
    # and thigh in the 5 fields where both were measured, then counted as placed, so the
    # ankle placed after it (210 fields) was never its partner: 5 fields, too few for a
    # name (14/15). A row too short to be named now waits for the rows placed after it.
    right, left = _legs(31)
    names = ("LHEE", "LTOE", "LANK", "LTIB", "LKNE", "LTHI", "RHEE", "RTOE", "RTIB", "RTHI")
    truth = np.concatenate([left, right[[0, 1, 3, 5]]])
    thigh = slice(8, truth.shape[1])  # the right thigh measured in its first 8 fields only
    tracks = _tracks_of(truth, {9: thigh})
    n = truth.shape[1]
    dlts = np.stack(
        [
            _look_at(right[2].mean(axis=0) + [2500.0, 1500.0, 600.0], right[2].mean(axis=0)),
            _look_at(right[4].mean(axis=0) + [-1500.0, 2500.0, 800.0], right[4].mean(axis=0)),
        ]
    )
    rng = np.random.default_rng(31)
    fields = np.arange(n)
    uv = np.r_[
        project_rows(dlts, np.zeros(n, int), right[2]),
        project_rows(dlts, np.ones(n, int), right[4]),
    ]
    noise = rng.uniform([0, 0], [640, 480], (2 * n, 2))
    spare = spare_blobs(
        np.r_[fields, fields, np.repeat(fields, 2)],
        np.r_[np.zeros(n), np.ones(n), np.tile([0, 1], n)],
        np.r_[uv + rng.normal(0, 0.05, uv.shape), noise],
        dlts,
    )
    out, _, named = fill_gaps_named(tracks, PARAMS, spare, names, (), ("RKNE", "RANK"))
    assert sorted(named) == ["RANK", "RKNE"]  # both named
    for name, j in (("RKNE", 4), ("RANK", 2)):
        rows = out.track == len(names) + named.index(name)
        # the knee: where tibia and ankle leave one depth (8 fields with the thigh alone)
        assert rows.sum() > n / 3
        err = np.linalg.norm(out.xyz_mm[rows] - right[j, out.field[rows]], axis=1)
        assert np.sqrt(np.mean(err**2)) < 2.0 and err.max() < 5.0


def test_blobs_that_fit_no_length_place_nothing():
    # every free blob in an image corner: none keeps the ankle's lengths (kiss 3 cameras
    # seed 103 raised IndexError when every ray of the fields with partners failed)
    right, truth = _feet(22)
    dense = _dense(_tracks_of(truth, {5: GAP, 6: GAP}))
    spare = _cameras(right, 22, GAP)
    corner = spare_blobs(spare.field, spare.camera, np.ones_like(spare.uv_px), spare.dlts)
    rows = absent_placed(dense, LABELS, ("RANK",), corner, PARAMS)[1]
    assert not np.isfinite(rows).any() and corner.free.all()


def test_an_ankle_measured_in_a_few_fields_joins_the_toe_s_segment_by_its_mirror_image():
    # kiss 3 seed 435: the right ankle, one camera's all trial, measured in 10 fields far
    # from the toe's gap, too few to judge its length to the toe; the toe's one ray square
    # to the heel-toe line. The left ankle's length to the left toe stands for it.
    right, truth = _feet(23)
    labels = (*LABELS, "RANK")
    dense = _dense(_tracks_of(np.concatenate([truth, right[2][None]]), {5: GAP, 6: GAP}))
    dense[7, :250] = dense[7, 260:] = np.nan
    spare = _cameras(right, 23, GAP)
    got = joint_ray_fill(
        dense, 5, GAP.start, GAP.stop, spare, PARAMS, None, mirror_tracks(labels, 8)
    )
    assert got is not None and 7 in got.partners
    # half the gap: where the heel's sphere and the ankle's ray fix the toe within
    # ray_length_max_error_mm; each placed field within twice what it expects
    placed = np.isfinite(got.sd_mm)
    assert placed.sum() >= 15
    err = np.linalg.norm(got.xyz_mm[placed] - right[1, GAP][placed], axis=1)
    assert np.sqrt(np.mean(err**2)) < 2.0 and np.all(err <= 2.0 * got.sd_mm[placed])


def test_a_blob_that_keeps_the_lengths_leaves_the_field_open_though_its_depth_is_loose():
    # a knee by its tibia and ankle: their spheres meet in a circle; the knee's own ray
    # crosses it at a glancing angle (its depth loose, SD over ray_length_max_error_mm),
    # a noise blob's ray 63 mm away crosses it squarely (kiss 3 seed 409: the knee's blob
    # fit with an SD of 5.1 mm, a noise blob with 2.4 and was placed 91 mm off)
    tib, ank = np.array([0.0, 0.0, 500.0]), np.array([60.0, 0.0, 290.0])
    length, sd = np.array([210.0, 420.0]), np.array([2.0, 2.0])
    axis = (ank - tib) / np.linalg.norm(ank - tib)
    along = (length[0] ** 2 - length[1] ** 2 + np.linalg.norm(ank - tib) ** 2) / (
        2 * np.linalg.norm(ank - tib)
    )
    u = np.cross(axis, [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    radius = np.sqrt(length[0] ** 2 - along**2)
    knee, noise = (
        tib + along * axis + radius * (np.cos(a) * u + np.sin(a) * v) for a in (np.pi, np.pi + 0.8)
    )
    centre = knee + [0.0, 3000.0, 300.0]
    dlts = _look_at(centre, knee)[None]
    n = 12
    dense = np.stack([np.tile(tib, (n, 1)), np.tile(ank, (n, 1))])
    uv = project_rows(dlts, np.zeros(2, dtype=int), np.stack([knee, noise]))
    spare = spare_blobs(np.repeat(np.arange(n), 2), np.zeros(2 * n), np.tile(uv, (n, 1)), dlts)
    _, worst, err = _depths(
        np.tile(centre, (2, 1)), ray_directions(dlts[[0, 0]], uv), dense[:, :2], length, sd
    )
    assert np.all(worst <= 3.0)  # both keep the lengths
    assert err[0] > PARAMS.ray_length_max_error_mm >= err[1]
    xyz, _ = place_absent(dense, np.array([0, 1]), length, sd, spare, PARAMS)
    placed = np.isfinite(xyz[:, 0])
    miss = np.linalg.norm(xyz[placed] - knee, axis=1)
    assert np.all(miss < 3.0 * PARAMS.ray_length_max_error_mm)  # nothing placed off the knee
    # the noise blob alone is placed: the lengths cannot tell it from the knee's
    alone = spare_blobs(np.arange(n), np.zeros(n), np.tile(uv[1], (n, 1)), dlts)
    assert np.isfinite(
        place_absent(dense, np.array([0, 1]), length, sd, alone, PARAMS)[0][:, 0]
    ).all()
