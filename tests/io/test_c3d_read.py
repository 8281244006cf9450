"""Reading C3D files as the standard defines them, on real files of three processor types
and two systems (fixtures/real/c3d/README.md) and on files written here for what the
real fixtures do not hold (model outputs, LABELS2, metres)."""

from __future__ import annotations

from pathlib import Path

import ezc3d
import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.io.c3d import processor_type, read_c3d
from tests.io.c3d_acceptance import retrack

REAL = Path(__file__).resolve().parents[2] / "fixtures" / "real" / "c3d"


def test_intel_dec_and_sgi_files_of_one_recording_read_the_same():
    """C3D.org's Sample02: one Vicon 370 recording in three processor formats; ezc3d
    reads Intel and DEC, the c3d package the SGI/MIPS one."""
    files = {k: read_c3d(REAL / f"{k}.c3d") for k in ("pc_real", "dec_int", "sgi_int")}
    assert {k: c.processor for k, c in files.items()} == {
        "pc_real": "Intel",
        "dec_int": "DEC",
        "sgi_int": "MIPS",
    }
    ref = files["pc_real"]
    assert ref.labels[:3] == ("RFT1", "RFT2", "RFT3") and len(ref.labels) == 36
    assert ref.n_frames == 89 and ref.first_frame == 1 and ref.rate_hz == 50.0
    for c in files.values():
        assert c.labels == ref.labels
        np.testing.assert_array_equal(np.isnan(c.xyz_mm), np.isnan(ref.xyz_mm))
        # integer files hold coordinates in steps of POINT:SCALE (0.28 mm here)
        assert np.nanmax(np.abs(c.xyz_mm - ref.xyz_mm)) <= 0.2812


def test_a_short_qualisys_file_keeps_its_frame_numbers_and_system():
    c = read_c3d(REAL / "FP_Type3.c3d")
    assert c.manufacturer.startswith("Qualisys")
    assert c.first_frame == 1166 and c.n_frames == 2 and len(c.labels) == 34
    assert np.isfinite(c.xyz_mm).all()


def test_a_nexus_file_with_the_oxford_foot_model_keeps_its_markers_only():
    """biomechZoo's Nexus walk (fixtures README): besides the declared outputs, the
    channels it does not declare are computed ones (the centre of mass on the floor, arch
    heights stored as points, the foot model's segment axes, a point at each heel
    marker) and are left out; the 74 markers stay, Plug-in Gait's and the foot model's."""
    c = read_c3d(REAL / "biomechzoo_nexus_ofm.c3d")
    assert c.manufacturer == "Vicon Vicon Nexus" and c.first_frame == 185 and c.n_frames == 30
    undeclared = {"CentreOfMassFloor", "LArchHeight", "RArchHeight", "LHE1", "RHE1"}
    undeclared |= {f"{s}{seg}{k}" for s in "LR" for seg in ("FOF", "HDF", "HLX") for k in "0123"}
    assert undeclared <= set(c.excluded) and len(c.labels) + len(c.excluded) == 290
    markers = {"LASI", "RASI", "SACR", "LHEE", "RHEE", "LTOE", "RTOE", "LHLX", "RP1M", "LCPG"}
    assert markers <= set(c.labels) and len(c.labels) == 74
    assert np.isfinite(c.xyz_mm).all()


def write(path: Path, labels, xyz_m_or_mm: np.ndarray, units="mm", **point_params) -> Path:
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [100.0]
    c["parameters"]["POINT"]["LABELS"]["value"] = list(labels)
    c.add_parameter("POINT", "UNITS", units)
    for name, value in point_params.items():
        c.add_parameter("POINT", name, value)
    n_frames, n_points, _ = xyz_m_or_mm.shape
    data = np.ones((4, n_points, n_frames))
    data[:3] = xyz_m_or_mm.transpose(2, 1, 0)
    c["data"]["points"] = data
    c.write(str(path))
    return path


def test_declared_model_outputs_are_left_out_and_named(tmp_path):
    rng = np.random.default_rng(0)
    labels = ("LASI", "LHipAngles", "RASI", "LHipPower", "LKJC", "LGRF")
    xyz = rng.uniform(-500, 500, (5, 6, 3))
    path = write(
        tmp_path / "m.c3d",
        labels,
        xyz,
        ANGLES=["LHipAngles"],
        POWERS2=["LHipPower"],  # an extension parameter of POWERS
        MODELED_MARKERS=["LKJC"],
        REACTIONS=["LGRF"],
    )
    c = read_c3d(path)
    assert c.labels == ("LASI", "RASI")
    assert set(c.excluded) == {"LHipAngles", "LHipPower", "LKJC", "LGRF"}
    np.testing.assert_allclose(c.xyz_mm, xyz[:, [0, 2]], atol=1e-3)


def test_plug_in_gait_segment_axes_are_left_out_and_named(tmp_path):
    """Plug-in Gait writes each segment's origin, anterior, lateral and proximal point as
    plain points (no model-output group): all four of a segment go, a label that only
    looks like one (three of the four, or a marker named like an axis) stays."""
    labels = (
        "Sub:PELO", "Sub:PELA", "Sub:PELL", "Sub:PELP",  # pelvis axes
        "Sub:LASI", "Sub:RASI",
        "Sub:LTOO", "Sub:LTOA", "Sub:LTOL",  # three of four: kept
        "Sub:STRN", "Sub:CLAV",
        "o_Trunk", "x_Trunk", "y_Trunk", "z_Trunk",  # origin and axis ends (C3D.org 11)
        "o_Arm", "x_Arm", "y_Arm",  # three of four: kept
    )  # fmt: skip
    xyz = np.random.default_rng(2).uniform(-500, 500, (4, len(labels), 3))
    c = read_c3d(write(tmp_path / "axes.c3d", labels, xyz))
    axes = {"Sub:PELO", "Sub:PELA", "Sub:PELL", "Sub:PELP"}
    assert set(c.excluded) == axes | {"o_Trunk", "x_Trunk", "y_Trunk", "z_Trunk"}
    kept = [i for i, lab in enumerate(labels) if lab not in c.excluded]
    assert c.labels == tuple(labels[i] for i in kept) and len(kept) == 10
    np.testing.assert_allclose(c.xyz_mm, xyz[:, kept], atol=1e-3)


def test_numbered_segment_axes_go_numbered_markers_stay(tmp_path):
    """The Oxford foot model's segment axes (``LFOF0`` ... ``LFOF3``: origin and three axis
    ends, beside Plug-in Gait's in a Nexus trial of the biomechZoo sample study) are left
    out; markers numbered the same way (``Marker_10`` ... ``Marker_13`` of an Optotrak
    file, ``PT00`` ... ``PT03``, ``LHDF1`` ... ``LHDF3`` without its origin) stay."""
    labels = (
        "Sub:LFOF0", "Sub:LFOF1", "Sub:LFOF2", "Sub:LFOF3",  # forefoot axes
        "LHDF1", "LHDF2", "LHDF3",  # no origin: kept
        "Marker_10", "Marker_11", "Marker_12", "Marker_13",
        "PT00", "PT01", "PT02", "PT03", "LHEE",
    )  # fmt: skip
    xyz = np.random.default_rng(4).uniform(-500, 500, (4, len(labels), 3))
    c = read_c3d(write(tmp_path / "ofm.c3d", labels, xyz))
    assert set(c.excluded) == {"Sub:LFOF0", "Sub:LFOF1", "Sub:LFOF2", "Sub:LFOF3"}
    assert c.labels == labels[4:]


def test_floor_projections_and_scalars_stored_as_points_are_left_out(tmp_path):
    """Nexus writes Plug-in Gait's ``CentreOfMassFloor`` (the centre of mass on the floor:
    z = 0 to the bit) and scalars as points (``LArchHeight``: x = y = 0) in no model-output
    group. A coordinate fixed to the bit while the channel moves is no measurement; a
    marker standing still, one seen in fewer than 10 samples, and a planar recording (every
    marker at z = 0) are kept."""
    rng = np.random.default_rng(5)
    n = 40
    walk = np.linspace(0, 1500, n)[:, None] + rng.normal(0, 0.3, (n, 3))
    still = np.array([300.0, 200.0, 100.0]) + rng.normal(0, 0.2, (n, 3))
    floor = walk * [1, 1, 0] + [0, 0, 0]
    scalar = np.zeros((n, 3))
    scalar[:, 2] = 20 + rng.normal(0, 2, n)
    few = walk * [1, 1, 0] + [0, 0, 7.5]
    few[8:] = np.nan  # 8 samples
    xyz = np.stack([walk, still, floor, scalar, few, walk + 100, still - 50], axis=1)
    labels = ("LASI", "RASI", "CentreOfMassFloor", "LArchHeight", "X", "LHEE", "LTOE")
    c = read_c3d(write(tmp_path / "com.c3d", labels, np.nan_to_num(xyz)))
    assert set(c.excluded) == {"CentreOfMassFloor", "LArchHeight"}
    assert c.labels == ("LASI", "RASI", "X", "LHEE", "LTOE")
    planar = xyz[:, [0, 1, 5, 6]] * [1, 1, 0]
    c = read_c3d(write(tmp_path / "plane.c3d", ("A", "B", "C", "D"), planar + [0, 0, 5]))
    assert c.excluded == () and len(c.labels) == 4


def test_a_file_whose_parameters_no_reader_parses_is_read_by_its_header(tmp_path):
    """A parameter offset pointing past the parameter section (as BTK's
    ``badParameterOffset.c3d`` and ``mocap36.c3d``): ezc3d and the c3d package both
    refuse the file, but the header lays out the data and fills the file, so the points
    are read by it, unnamed, at the header's rate. Cut short as well, the file is one
    clear error (without ezc3d's advice to set its own flags)."""
    xyz = np.random.default_rng(6).uniform(-900, 900, (20, 3, 3))
    raw = bytearray(write(tmp_path / "ok.c3d", ("A", "B", "C"), xyz, RATE=[120.0]).read_bytes())
    start = (raw[0] - 1) * 512 + 4  # the first group: name length, id, name, offset
    at = start + 2 + raw[start]
    raw[at : at + 2] = (32767).to_bytes(2, "little")
    bad = tmp_path / "bad.c3d"
    bad.write_bytes(bytes(raw))
    with pytest.raises(Exception):  # noqa: B017 (ezc3d refuses it)
        ezc3d.c3d(str(bad))
    c = read_c3d(bad)
    assert c.labels == ("point1", "point2", "point3") and c.rate_hz == 120.0
    assert c.n_frames == 20 and c.first_frame == 1
    np.testing.assert_allclose(c.xyz_mm, xyz, atol=1e-3)
    bad.write_bytes(bytes(raw[: 512 * raw[0]]))  # the parameters only
    with pytest.raises(KisscalError, match="not a readable C3D file") as err:
        read_c3d(bad)
    assert "ignoreBadFormatting" not in str(err.value)


def test_a_channel_that_copies_another_marker_is_left_out(tmp_path):
    """Writers store points at a marker's place beside it (the Oxford foot model's ``LHE1``
    0.8 mm from ``LHEE``, Cortex's virtual ``VRTO`` on ``R.TO``, a Qualisys file holding
    every marker three times): within 5 mm of another channel wherever it is seen, it is
    that marker again, and of the two the one seen less goes. Two markers passing within
    3 mm of each other in one frame are two markers."""
    rng = np.random.default_rng(7)
    n = 40
    path = np.linspace([0, 0, 900], [1500, 100, 950], n)
    heel = path + rng.normal(0, 0.3, (n, 3))
    copy = heel + rng.normal(0, 0.5, (n, 3))
    toe = path + [150, 60, -850] + rng.normal(0, 0.3, (n, 3))
    toe_filled = toe + rng.normal(0, 0.5, (n, 3))
    toe[30:] = 0.0  # missing: the copy is seen longer
    swing = path + [0, 100, 0] + np.linspace(0, 200, n)[:, None] * [0, -1, 0]
    swing[20] = heel[20] + [0, 3, 0]  # passes within 3 mm of the heel once
    xyz = np.stack([heel, toe, copy, toe_filled, swing], axis=1)
    labels = ("LHEE", "LTOE", "LHE1", "LTOE2", "LWRA")
    c = read_c3d(write(tmp_path / "copies.c3d", labels, xyz))
    assert set(c.excluded) == {"LHE1", "LTOE"}
    assert c.labels == ("LHEE", "LTOE2", "LWRA")


def test_labels_continue_in_labels2_and_metres_become_mm(tmp_path):
    xyz = np.random.default_rng(1).uniform(-1, 1, (3, 4, 3))
    path = write(tmp_path / "l.c3d", ("A", "B"), xyz, units="m", LABELS2=["C", "D"])
    c = read_c3d(path)
    assert c.labels == ("A", "B", "C", "D")
    np.testing.assert_allclose(c.xyz_mm, 1000.0 * xyz, atol=1e-2)


def test_not_a_c3d_is_one_clear_error(tmp_path):
    bad = tmp_path / "x.c3d"
    bad.write_bytes(b"\x02\x11" + bytes(600))
    with pytest.raises(KisscalError, match="not a C3D file"):
        processor_type(bad)
    with pytest.raises(KisscalError, match="not found"):
        read_c3d(tmp_path / "missing.c3d")


def test_a_file_whose_parameters_misdescribe_the_data_is_read_by_its_header():
    """C3D.org's Sample27 (Kyowa Dengyo, DEC integer): POINT:USED says 12 points and
    POINT:FRAMES 145, the header and the file's size 11 points in 152 frames. Laid out
    by the parameters (as ezc3d reads it) every frame is shifted: a marker moves 373 mm a
    frame (median) and up to 2 m; laid out by the header, 20 mm (1.2 m/s at 60 Hz) and
    at most 70 mm (a foot in swing)."""
    c = read_c3d(REAL / "kyowadengyo.c3d")
    assert c.processor == "DEC" and len(c.labels) == 11 and c.n_frames == 152
    assert c.first_frame == 33
    step = np.linalg.norm(np.diff(c.xyz_mm, axis=0), axis=2)
    assert np.nanmedian(step) < 30.0 and np.nanmax(step) < 100.0  # walking, not noise
    # re-tracked from shuffled anonymous points (issue 26's acceptance): read by the
    # parameters it gave 1121 identity switches
    r = retrack(c.xyz_mm, c.rate_hz)
    assert r.switches == 0 and r.coverage > 0.99
    assert np.isfinite(c.xyz_mm).all(axis=2).mean() > 0.9


def test_header_layout_decodes_intel_dec_and_mips_files_as_the_readers_do():
    """The header decoder gives the samples ezc3d (Intel, DEC) and the c3d package (SGI)
    give, integer and float, on one recording in three processor formats."""
    from kisscal.io.c3d_data import read_points_by_header

    ref = read_c3d(REAL / "pc_real.c3d")
    for name, kind in (("pc_real", "Intel"), ("dec_int", "DEC"), ("sgi_int", "MIPS")):
        xyz, word, first = read_points_by_header(REAL / f"{name}.c3d", kind)
        xyz = np.where((word < 0)[..., None], np.nan, xyz)
        assert first == 1 and xyz.shape == ref.xyz_mm.shape
        np.testing.assert_array_equal(np.isnan(xyz), np.isnan(ref.xyz_mm))
        assert np.nanmax(np.abs(xyz - ref.xyz_mm)) <= 0.2812


def test_odd_parameters_units_words_two_d_values_and_zero_samples(tmp_path):
    """Unit words (Peak Performance writes 'mete'), a parameter stored as a 1 x 2 array
    (A.R.T.'s TRIAL:ACTUAL_START_FIELD) and samples stored at 0 0 0 with a valid
    residual (older writers' missing sample) read as the standard means them."""
    xyz = np.random.default_rng(3).uniform(0.2, 1.5, (4, 3, 3))
    xyz[2, 1] = 0.0
    path = write(tmp_path / "u.c3d", ("A", "B", "C"), xyz, units="mete")
    c = read_c3d(path)
    np.testing.assert_allclose(c.xyz_mm[np.isfinite(c.xyz_mm)], 1000 * xyz[xyz != 0], atol=0.1)
    assert np.isnan(c.xyz_mm[2, 1]).all() and np.isfinite(c.xyz_mm).all(axis=2).sum() == 11
    e = ezc3d.c3d(str(path))
    e.add_parameter("TRIAL", "ACTUAL_START_FIELD", [7, 0])
    e["parameters"]["TRIAL"]["ACTUAL_START_FIELD"]["value"] = np.array([[7.0, 0.0]])
    e.write(str(tmp_path / "t.c3d"))
    assert ezc3d.c3d(str(tmp_path / "t.c3d"))["parameters"]["TRIAL"]["ACTUAL_START_FIELD"][
        "value"
    ].shape == (1, 2)
    assert read_c3d(tmp_path / "t.c3d").first_frame == 7
    with pytest.raises(KisscalError, match="unsupported point units"):
        read_c3d(write(tmp_path / "i.c3d", ("A",), xyz[:, :1], units="inch"))
