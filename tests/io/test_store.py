"""SessionStore: the out/ layout of DESIGN.md, and the one key of a stage's inputs."""

from __future__ import annotations

import dataclasses
import os
import shutil

import numpy as np
import pytest

from kisscal.camera import Camera
from kisscal.errors import KisscalError
from kisscal.grid.poly import LinearisationQuality, identity_linearisation
from kisscal.io.store import SessionStore
from kisscal.rig import Rig


def test_layout_is_the_public_contract(tmp_path):
    store = SessionStore(tmp_path)
    rel = {
        name: path.relative_to(tmp_path).as_posix()
        for name, path in {
            "lin": store.linearisation_path("cam1"),
            "dlt": store.dlt_path("cam1"),
            "dltdv": store.dltdv_path,
            "wand": store.calibration_file("wand"),
            "detection": store.detection_path("cam1"),
            "points3d": store.trial("walk01").points3d,
            "points2d": store.trial("walk01").points2d,
            "trc": store.trial("walk01").trajectories(".trc"),
            "events": store.trial("walk01").events,
            "toml": store.cameras_toml_path,
            "summary": store.summary_path,
            "report": store.report_path,
        }.items()
    }
    assert rel == {
        "lin": "out/linearisation/cam1.json",
        "dlt": "out/dlt/cam1.json",
        "dltdv": "out/dlt/dltdv.csv",
        "wand": "out/dlt/wand.json",
        "detection": "out/detection/cam1.json",
        "points3d": "out/trials/walk01/points3d.csv",
        "points2d": "out/trials/walk01/points2d.csv",
        "trc": "out/trials/walk01/trajectories.trc",
        "events": "out/trials/walk01/events.csv",
        "toml": "out/cameras.toml",
        "summary": "out/summary.json",
        "report": "out/report.html",
    }
    with pytest.raises(KisscalError, match="no calibration file 'rods'"):
        store.calibration_file("rods")


def test_a_moved_session_keeps_its_keys_and_an_edited_input_changes_them(tmp_path):
    a = tmp_path / "a"
    (a / "grid").mkdir(parents=True)
    image = a / "grid" / "0.png"
    image.write_bytes(b"\x89PNG one")
    key = SessionStore(a).key("linearise", [image], {"rows": 15})
    b = tmp_path / "b"
    shutil.copytree(a, b)
    os.utime(b / "grid" / "0.png", ns=(image.stat().st_atime_ns, image.stat().st_mtime_ns))
    assert SessionStore(b).key("linearise", [b / "grid" / "0.png"], {"rows": 15}) == key
    assert SessionStore(a).key("linearise", [image], {"rows": 16}) != key
    image.write_bytes(b"\x89PNG two, longer")
    assert SessionStore(a).key("linearise", [image], {"rows": 15}) != key


def test_a_linearisation_is_keyed_by_its_coefficients_alone(tmp_path):
    store = SessionStore(tmp_path)
    lin = identity_linearisation((320.0, 240.0), 320.0)
    figures = {f.name: 0.5 for f in dataclasses.fields(LinearisationQuality)}
    fitted = dataclasses.replace(lin, quality=LinearisationQuality(**figures))
    assert lin.quality is None  # as read back from a file without its quality figures
    assert store.key({"cam1": lin}) == store.key({"cam1": fitted})
    moved = identity_linearisation((321.0, 240.0), 320.0)
    assert store.key({"cam1": lin}) != store.key({"cam1": moved})


def test_a_rig_is_keyed_by_its_dlts_lenses_and_linearisations(tmp_path):
    store = SessionStore(tmp_path)
    L = np.arange(1.0, 12.0)
    lin = identity_linearisation((320.0, 240.0), 320.0)
    rig = Rig((Camera.from_dlt(L, "cam1", lin),))
    same = Camera.from_dlt(L.copy(), "cam1", lin, size_px=(640, 480))
    assert store.key(rig) == store.key(Rig((same,)))
    assert store.key(rig) != store.key(Rig((Camera.from_dlt(L + 1e-9, "cam1", lin),)))
    assert store.key(rig) != store.key(Rig((Camera.from_dlt(L, "cam1", lin, np.ones(5)),)))


def test_an_output_is_current_only_for_the_key_it_was_written_for(tmp_path):
    store = SessionStore(tmp_path)
    out = store.calibration_file("check")
    assert not store.is_current(out, "k1")
    out.parent.mkdir(parents=True)
    out.write_text("{}")
    assert not store.is_current(out, "k1")  # written, but for no key
    store.mark_current(out, "k1")
    assert store.is_current(out, "k1") and not store.is_current(out, "k2")
    store.forget(out)
    assert out.is_file() and not store.is_current(out, "k1")


def test_readers_say_none_when_absent_and_name_a_broken_file(tmp_path):
    store = SessionStore(tmp_path)
    assert store.calibration_doc("wand") is None and store.detection_record("cam1") is None
    assert not store.has_results()
    with pytest.raises(KisscalError, match="DLT file not found"):
        store.dlt("cam1")
    path = store.calibration_file("wand")
    path.parent.mkdir(parents=True)
    path.write_text("{not json")
    with pytest.raises(KisscalError, match=r"wand\.json: not valid JSON"):
        store.calibration_doc("wand")
    assert store.has_results()  # a dlt/*.json exists
