"""Rod recognition: identified and ordered by a projective invariant, ambiguity refused."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt import DltParams, make_rods, project, recognise_rods, rod_distinctness
from kisscal.errors import KisscalError
from tests.dlt.conftest import ROD_XY_MM, ROD_Z_MM, kiss_rig, rod_image


@pytest.mark.parametrize("seed", range(20))
def test_recognition_on_20_rigs_with_noise_and_a_hidden_marker(seed):
    rig = kiss_rig(seed)
    rng = np.random.default_rng(1000 + seed)
    hidden_cam = seed % 6
    hidden = int(rng.integers(24))
    for cam in range(6):
        hide = hidden if cam == hidden_cam else None
        blobs, truth = rod_image(rig, cam, rng, noise_px=0.05, n_extra=8, hide=hide)
        match = recognise_rods(blobs, rig.rods, camera=f"cam{cam + 1}")
        np.testing.assert_array_equal(match.blob_index.ravel(), truth)
        # Hidden or merged markers (rods aligned in the view), named in the report
        absent = tuple(f"R{j // 6 + 1}.{j % 6 + 1}" for j in np.flatnonzero(truth < 0))
        assert match.missing == absent
        if hide is not None:
            assert f"R{hidden // 6 + 1}.{hidden % 6 + 1}" in absent
        assert np.all(match.fit_rms_px < 0.3)
        assert len(match.unused_blobs) == 8


def test_control_points_and_marker_uv(rig):
    rng = np.random.default_rng(2)
    blobs, _ = rod_image(rig, 0, rng, hide=7)
    match = recognise_rods(blobs, rig.rods)
    xyz, uv, labels = match.control_points(blobs, rig.rods)
    assert len(xyz) == len(uv) == len(labels) == 23
    assert "R2.2" not in labels and labels[0] == "R1.1"
    np.testing.assert_allclose(uv, project(rig.L[0], xyz), atol=0.3)
    muv = match.marker_uv(blobs)
    assert muv.shape == (4, 6, 2) and np.isnan(muv[1, 1]).all()


def test_rod_out_of_view_is_reported_missing(rig):
    rng = np.random.default_rng(4)
    blobs, truth = rod_image(rig, 3, rng, n_extra=3)
    keep = np.setdiff1d(np.arange(len(blobs)), truth[12:18])  # R3 out of the picture
    match = recognise_rods(blobs[keep], rig.rods, camera="cam4")
    assert match.missing == tuple(f"R3.{i}" for i in range(1, 7))
    assert np.all(match.blob_index[2] == -1)
    assert np.isnan(match.fit_rms_px[2])


def test_spacings_that_are_not_unique_are_refused():
    same = [[[0, 0, z] for z in ROD_Z_MM["R1"]], [[2400, 0, z] for z in ROD_Z_MM["R1"]]]
    with pytest.raises(KisscalError, match="marker spacings are not unique: rods R1 and R2"):
        recognise_rods(np.zeros((12, 2)), make_rods([("R1", same[0]), ("R2", same[1])]))
    # A rod scaled about its top marker has the same cross-ratios: also refused.
    z = np.array(ROD_Z_MM["R2"], float)
    scaled = 1900 - 0.8 * (1900 - z)
    rods = make_rods([("A", [[0, 0, v] for v in z]), ("B", [[0, 1400, v] for v in scaled])])
    assert rod_distinctness(rods, 6)[0, 1] < 1e-9
    with pytest.raises(KisscalError, match=r"rods A and B"):
        recognise_rods(np.zeros((12, 2)), rods)


def test_partial_view_that_fits_two_rods_is_refused():
    # Rods A and B differ only in their second marker; with that marker hidden and rod B
    # out of view, the 5 blobs fit both: refuse, naming the camera and both rods.
    za = [1900, 1660, 1440, 680, 530, 100]
    zb = [1900, 1200, 1440, 680, 530, 100]
    zb = sorted(zb, reverse=True)
    zc = ROD_Z_MM["R3"]
    rods = make_rods(
        [
            ("A", [[*ROD_XY_MM["R1"], v] for v in za]),
            ("B", [[*ROD_XY_MM["R2"], v] for v in zb]),
            ("C", [[*ROD_XY_MM["R3"], v] for v in zc]),
        ]
    )
    rig = kiss_rig(0)
    uv = project(rig.L[0], rods[0].points_mm)
    blobs = np.concatenate([uv[[0, 2, 3, 4, 5]], project(rig.L[0], rods[2].points_mm)])
    with pytest.raises(KisscalError, match=r"camera cam1: .*rods (A and B|B and A)"):
        recognise_rods(blobs, rods, camera="cam1")


def test_rod_config_errors():
    with pytest.raises(KisscalError, match="top to bottom"):
        make_rods([("R1", [[0, 0, z] for z in ROD_Z_MM["R1"][::-1]])])
    with pytest.raises(KisscalError, match="not straight"):
        make_rods([("R1", [[0, 0, 1900], [0, 0, 1500], [300, 0, 1000], [0, 0, 100]])])
    with pytest.raises(KisscalError, match="used twice"):
        make_rods([("R1", [[0, 0, z] for z in ROD_Z_MM["R1"]])] * 2)
    with pytest.raises(KisscalError, match="at least 4 markers"):
        make_rods([("R1", [[0, 0, 1900], [0, 0, 100]])])


def test_tolerances_are_parameters(rig):
    rng = np.random.default_rng(9)
    blobs, _ = rod_image(rig, 1, rng, noise_px=1.5)
    strict = recognise_rods(blobs, rig.rods, DltParams(rod_fit_tol_px=0.2, rod_line_tol_px=0.2))
    assert len(strict.missing) > 0


def test_rods_in_line_are_never_misidentified():
    # End cameras at X = -300 and 2700 see two rods nearly in line (10-12 blobs on one
    # image line, some markers merged). Identification may drop markers or refuse but
    # must never assign a blob to the wrong marker.
    complete = wrong = 0
    for seed in range(12):
        rig = kiss_rig(seed, xs=(-300, 1200, 2700))
        rng = np.random.default_rng(seed)
        for cam in (0, 1, 4, 5):
            blobs, truth = rod_image(rig, cam, rng, n_extra=8, hide=int(rng.integers(24)))
            try:
                got = recognise_rods(blobs, rig.rods).blob_index.ravel()
            except KisscalError:
                continue
            wrong += int(np.any((got >= 0) & (got != truth)))
            complete += int(np.array_equal(got, truth))
    assert wrong == 0
    assert complete >= 44  # of 48


def test_chance_alignments_grow_with_the_density_of_blobs():
    from kisscal.dlt.rods import chance_alignments

    rng = np.random.default_rng(0)
    few, many = (rng.uniform([0, 0], [751, 290], (n, 2)) for n in (30, 1300))
    assert chance_alignments(few, 1.5) < 0.5 < 10 < chance_alignments(many, 1.5)
    # lines through two of 1300 random blobs collect about that many others (the bound
    # takes the longest line across; lines through the box are shorter on average)
    counts = []
    for _ in range(200):
        i, j = rng.choice(len(many), 2, replace=False)
        d = many[j] - many[i]
        normal = np.array([-d[1], d[0]]) / np.linalg.norm(d)
        counts.append((np.abs((many - many[i]) @ normal) < 1.5).sum() - 2)
    assert 0.5 < np.mean(counts) / chance_alignments(many, 1.5) <= 1.0


def test_a_hopeless_rod_image_is_refused_at_once_with_bounded_memory(rig):
    # ~1300 clutter blobs (a once 17.7 GiB search): one clear line, no search at all
    import tracemalloc

    blobs, _ = rod_image(rig, 0, np.random.default_rng(3), n_extra=1300)
    tracemalloc.start()
    with pytest.raises(KisscalError, match=r"cam1: 1324 blobs in the rod image, too many"):
        recognise_rods(blobs, rig.rods, camera="cam1")
    assert tracemalloc.get_traced_memory()[1] < 20e6
    tracemalloc.stop()


def test_a_busy_rod_image_is_still_recognised_within_bounded_memory(rig):
    import tracemalloc

    rng = np.random.default_rng(4)
    blobs, truth = rod_image(rig, 0, rng, n_extra=60)
    tracemalloc.start()
    match = recognise_rods(blobs, rig.rods, camera="cam1")
    assert tracemalloc.get_traced_memory()[1] < 50e6
    tracemalloc.stop()
    np.testing.assert_array_equal(match.blob_index.ravel(), truth)


def test_the_number_of_candidate_lines_is_capped(rig):
    blobs, _ = rod_image(rig, 0, np.random.default_rng(4), n_extra=60)
    with pytest.raises(KisscalError, match=r"cam1: more than 10 lines of 5 or more blobs"):
        recognise_rods(blobs, rig.rods, DltParams(rod_max_lines=10), camera="cam1")
