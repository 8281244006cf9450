"""Shipped marker sets: loading, selection, self-consistent templates, scaling, errors."""

from __future__ import annotations

from importlib import resources

import numpy as np
import pytest

from kisscal.errors import KisscalError
from kisscal.markersets import available_marker_sets, marker_set
from kisscal.markersets.loader import tomllib
from kisscal.synth.motion import gait_marker_names, gait_segments, standing_template, walking_trial
from tests.markersets.derive_markersets import WALKING5_ALIASES, tables

SETS = ("kiss", "plug-in-gait-full", "plug-in-gait-lower")


def test_the_three_sets_are_shipped_with_their_sizes() -> None:
    assert available_marker_sets() == SETS
    assert len(marker_set("plug-in-gait-lower")) == 16
    assert len(marker_set("plug-in-gait-full")) == 39
    assert marker_set("kiss").names == gait_marker_names(15)


def test_data_files_are_what_the_documented_derivation_gives() -> None:
    for stem, table in tables().items():
        text = resources.files("kisscal.markersets").joinpath("data", f"{stem}.toml").read_text()
        assert tomllib.loads(text) == table, stem


@pytest.mark.parametrize("name", SETS)
def test_templates_mirror_across_the_sagittal_plane(name: str) -> None:
    full = marker_set(name)
    assert full.mirror, name
    for left, right in full.mirror:
        np.testing.assert_allclose(full.position(left), full.position(right) * [1, -1, 1])
        assert full.position(left)[1] > 0  # left is +Y
        assert full.mirror_of(left) == right and full.mirror_of(right) == left
    for name_ in full.midline:
        assert full.position(name_)[1] == 0.0
    sd = dict(zip(full.names, full.sd_mm, strict=True))
    assert all(sd[a] == sd[b] for a, b in full.mirror)


@pytest.mark.parametrize("name", SETS)
def test_templates_stand_on_the_floor_and_segments_are_paired(name: str) -> None:
    s = marker_set(name)
    z = s.template_mm[:, 2]
    assert 20.0 < z.min() < 60.0  # foot markers just above the floor (Z = 0)
    lengths = s.segment_lengths_mm(hinge=True)
    assert all(20.0 < d < 1000.0 for d in lengths.values())
    for (a, b), d in lengths.items():  # a left segment is as long as its right mirror
        ma, mb = s.mirror_of(a), s.mirror_of(b)
        if ma and mb and (ma, mb) in lengths:
            assert lengths[(ma, mb)] == pytest.approx(d, abs=1e-6)


def test_kiss_template_is_the_walkers_standing_pose_and_its_segments_stay_rigid() -> None:
    kiss = marker_set("kiss")
    np.testing.assert_allclose(kiss.template_mm, standing_template(kiss.names), atol=0.01)
    assert set(kiss.segments) == set(gait_segments(kiss.names))
    m = walking_trial(4, 120, model="grounded")
    for (a, b), length in kiss.segment_lengths_mm().items():
        d = np.linalg.norm(m.xyz_mm[:, m.names.index(a)] - m.xyz_mm[:, m.names.index(b)], axis=1)
        assert np.ptp(d) < 1e-6
        assert d[0] == pytest.approx(length, abs=0.02)  # rigid in the template as in motion


def test_plug_in_gait_geometry_fits_the_walking5_subject_within_its_sd() -> None:
    """Distances of walking5's own markers (mapped by the set's aliases) against the
    template scaled to that subject's stature (from its ASIS height)."""
    from kisscal.io.c3d import read_c3d_points

    labels, xyz, _ = read_c3d_points(resources.files("kisscal.data") / "walking5.c3d")
    pig = marker_set("plug-in-gait-full")
    track = {pig.aliases.get(n, n): xyz[:, i] for i, n in enumerate(labels)}
    asis_z = np.nanmedian(track["LASI"][:, 2])
    subject = pig.scaled(pig.height_mm * asis_z / pig.position("LASI")[2])
    sd = subject.segment_sd_mm(hinge=True)
    for (a, b), length in subject.segment_lengths_mm(hinge=True).items():
        if a in track and b in track:
            measured = np.nanmedian(np.linalg.norm(track[a] - track[b], axis=1))
            assert abs(measured - length) < 3.0 * sd[(a, b)], (a, b, measured, length)


def test_scaling_with_height_is_isometric() -> None:
    pig = marker_set("plug-in-gait-lower")
    tall = pig.scaled(1900.0)
    np.testing.assert_allclose(tall.template_mm, pig.template_mm * 1900.0 / 1750.0)
    np.testing.assert_allclose(tall.sd_mm, pig.sd_mm * 1900.0 / 1750.0)
    assert tall.height_mm == 1900.0 and tall.reference_height_mm == 1750.0
    short = tall.scaled(1500.0)
    np.testing.assert_allclose(short.template_mm, pig.template_mm * 1500.0 / 1750.0)
    with pytest.raises(KisscalError, match="height"):
        pig.scaled(float("nan"))


def test_names_pick_variants_and_order() -> None:
    names = ["RASI", "LASI", "SACR", "LTHI", "LKNE", "LTIB", "LANK", "LHEE", "LTOE"]
    s = marker_set("plug-in-gait-lower", names=names)
    assert s.names == tuple(names)
    rasi = marker_set("plug-in-gait-lower").position("RASI")
    np.testing.assert_array_equal(s.template_mm[0], rasi)
    assert ("RASI", "SACR") in s.segments and not any("LPSI" in p for p in s.segments)
    assert s.pelvis == ("LASI", "RASI", "SACR")
    assert s.foot("left") == {"heel": "LHEE", "toe": "LTOE", "ankle": "LANK"}
    assert s.foot("right") == {}
    kiss13 = marker_set("kiss", names=gait_marker_names(13))
    assert len(kiss13) == 13 and ("RASI", "LASI") not in kiss13.mirror


def test_aliases_name_walking5_markers() -> None:
    pig = marker_set("plug-in-gait-full")
    assert dict(pig.aliases) == WALKING5_ALIASES
    s = marker_set("plug-in-gait-full", names=["LCAL", "RCAL", "LMT2"])
    assert s.names == ("LHEE", "RHEE", "LTOE")


@pytest.mark.parametrize(
    ("call", "words"),
    [
        (lambda: marker_set("plugin-gait-lower"), "did you mean 'plug-in-gait-lower'"),
        (lambda: marker_set("vicon"), "kisscal ships: kiss, plug-in-gait-full"),
        (lambda: marker_set("kiss", names=["SACR", "RHE"]), "did you mean 'RHEE'"),
        (lambda: marker_set("kiss", names=["SACR", "SACR"]), "given twice"),
        (lambda: marker_set("kiss").foot("up"), "side must be"),
    ],
)
def test_errors_are_one_line_kisscal_errors(call, words: str) -> None:
    with pytest.raises(KisscalError) as err:
        call()
    assert words in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("name", SETS)
def test_a_marker_set_pickles_with_its_read_only_roles(name: str) -> None:
    """A marker set travels to the figure process (tracking results carry one)."""
    import pickle
    from types import MappingProxyType

    full = marker_set(name)
    back = pickle.loads(pickle.dumps(full, protocol=pickle.HIGHEST_PROTOCOL))
    assert isinstance(back.roles, MappingProxyType) and dict(back.roles) == dict(full.roles)
    assert back.names == full.names and back.foot("left") == full.foot("left")
