"""Session format version 2: new tables, references between tables, forgiving text files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import tomli_w

from kisscal.errors import KisscalError
from kisscal.io.config import load_session, load_toml, parse_session

BASE = {
    "session": {"name": "lab", "rate_hz": 100},
    "cameras": [{"id": "c1", "size": [1280, 1024]}, {"id": "c2"}],
    "trials": [
        {"name": "wand01", "images": "trials/wand01/{camera}/*.png"},
        {"name": "static01", "images": "trials/static01/{camera}/*.png"},
        {"name": "walk02", "c3d": "trials/walk02.c3d"},
        {"name": "walk03", "video": "trials/walk03/{camera}.avi", "fields": "top-first"},
    ],
}


def parse(**tables: object) -> object:
    return parse_session({**BASE, **tables}, Path("/lab"))


def test_version_2_tables_parse() -> None:
    config = parse(
        wand={"trial": "wand01", "markers_mm": [0, 250, 500]},
        axes={
            "images": "axes/{camera}/*.png",
            "points_mm": [[0, 0, 0], [400, 0, 0], [0, 300, 0], [150, 0, 0]],
        },
        markers={"set": "plug-in-gait-lower", "static": "static01"},
        export={"trc_up": "y", "volume_mm": [[1500, 750, 0], [-1500, -750, 1800]]},
    )
    assert config.wand.markers_mm == (0.0, 250.0, 500.0)
    assert config.axes.points_mm.shape == (4, 3)
    assert config.markers.set == "plug-in-gait-lower" and config.markers.names == ()
    assert config.export.trc_up == "y"
    assert config.export.volume_mm == ((-1500, -750, 0), (1500, 750, 1800))
    assert parse().export.volume_mm is None
    assert config.cameras[1].size_px is None
    assert [t.source for t in config.trials] == ["images", "images", "c3d", "video"]
    assert config.trial("walk03").fields == "top-first"


def test_calibration_names_map_foreign_cameras() -> None:
    config = parse(calibration={"cameras": "c.toml", "names": {"cam_01": "c1", "cam_02": "c2"}})
    assert config.calibration.names == {"cam_01": "c1", "cam_02": "c2"}
    assert parse(calibration={"cameras": "c.toml"}).calibration.names == {}


@pytest.mark.parametrize(
    ("tables", "message"),
    [
        ({"wand": {"trial": "wand1", "markers_mm": [0, 500]}}, "did you mean 'wand01'"),
        ({"wand": {"trial": "wand01", "markers_mm": [500]}}, "2 or more"),
        ({"wand": {"trial": "wand01", "markers_mm": [0, 500], "lenght": 1}}, "unknown key wand."),
        ({"markers": {"set": "plug-in-gait-lower", "static": "static1"}}, "markers.static"),
        ({"markers": {}}, "needs names or a set"),
        ({"calibration": {"cameras": "a.toml", "dlt": "b.csv"}}, "exactly one of"),
        (
            {"calibration": {"target": "t.csv", "images": "x/{camera}/*.tif"}},
            "missing key calibration.'seeds'",
        ),
        (
            {"axes": {"images": "a", "points_mm": [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0]]}},
            "collinear",
        ),
        ({"export": {"trc_up": "x"}}, "one of 'z', 'y'"),
        ({"export": {"volume_mm": [[0, 0, 0]]}}, "volume_mm must be two opposite corners"),
        ({"export": {"volume_mm": [[0, 0, 0], [1, 1]]}}, "list of \\[x, y, z\\] in mm"),
        ({"export": {"volume_mm": [[0, 0, 0], [1, 1, 0]]}}, "differing in x, y and z"),
        ({"export": {"volume_mm": "lab"}}, "list of \\[x, y, z\\] in mm"),
        (
            {"calibration": {"cameras": "c.toml", "names": {"cam_01": "cam1"}}},
            "maps 'cam_01' to 'cam1', which is not a camera id",
        ),
        ({"calibration": {"cameras": "c.toml", "names": {"cam_01": "c11"}}}, "did you mean 'c1'"),
        ({"calibration": {"cameras": "c.toml", "names": ["c1"]}}, "must be a table of names"),
        (
            {"calibration": {"cameras": "c.toml", "names": {"a": "c1", "b": "c1"}}},
            "two names onto one camera",
        ),
        ({"calibration": {"points": "p/{camera}.csv", "names": {"a": "c1"}}}, "not points"),
        ({"calibration": {"cameras": "c.toml", "name": {"a": "c1"}}}, "did you mean 'names'"),
    ],
)
def test_version_2_mistakes_are_one_line_errors(tables: dict, message: str) -> None:
    with pytest.raises(KisscalError, match=message) as err:
        parse(**tables)
    assert "\n" not in str(err.value)


def test_fields_only_for_images_or_video() -> None:
    trials = [{"name": "t", "centroids": "x/{camera}.csv", "fields": "top-first"}]
    with pytest.raises(KisscalError, match="applies to images or video only"):
        parse_session({**BASE, "trials": trials}, Path("/lab"))
    trials = [{"name": "t", "images": "x/{camera}/*.png", "fields": "bottom-first"}]
    assert parse_session({**BASE, "trials": trials}, Path("/lab")).trials[0].fields == (
        "bottom-first"
    )


def test_duplicate_camera_and_trial_names() -> None:
    cams = [{"id": "c1"}, {"id": "c1"}]
    with pytest.raises(KisscalError, match="repeated: c1"):
        parse_session({**BASE, "cameras": cams}, Path("/lab"))
    trials = [BASE["trials"][0], BASE["trials"][0]]
    with pytest.raises(KisscalError, match="repeated: wand01"):
        parse_session({**BASE, "trials": trials}, Path("/lab"))


def test_bom_and_crlf_are_read(tmp_path: Path) -> None:
    text = tomli_w.dumps(BASE).replace("\n", "\r\n")
    (tmp_path / "session.toml").write_bytes(b"\xef\xbb\xbf" + text.encode())
    config = load_session(tmp_path)
    assert config.camera_ids == ("c1", "c2")


def test_not_utf8_is_named(tmp_path: Path) -> None:
    (tmp_path / "session.toml").write_bytes(b"[session]\nname = '\xff\xfe'\n")
    with pytest.raises(KisscalError, match="not UTF-8"):
        load_toml(tmp_path / "session.toml")


def test_missing_size_comes_from_the_first_frame(small_session: Path, tmp_path: Path) -> None:
    import shutil

    from kisscal.session.inputs import load_config

    session = tmp_path / "s"
    shutil.copytree(small_session, session, ignore=shutil.ignore_patterns("out"))
    data = load_toml(session / "session.toml")
    sizes = [tuple(c.pop("size")) for c in data["cameras"]]
    (session / "session.toml").write_text(tomli_w.dumps(data))
    config = load_config(session)
    assert [c.size_px for c in config.cameras] == sizes
    assert np.all(np.array(sizes) > 0)
