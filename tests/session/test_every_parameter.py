"""Every parameter of every stage, set in ``session.toml``, reaches what the stage receives.

For each field of each parameter class the session resolves (:data:`MEMBERS`), a
``session.toml`` setting a valid value other than the default is written, loaded and
resolved (:func:`kisscal.session.stage_params`), and the resolved parameters must carry
that value. The settings the detection survey derives per camera are walked through the
survey too: a value given in ``[detection]`` must be the value the camera's detection
receives. A few end-to-end checks then show that a setting changes what a stage does.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import typing
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np
import pytest
import tomli_w

from kisscal.bundle import resect
from kisscal.bundle.adjust import ControlPoints
from kisscal.bundle.params import BundleParams
from kisscal.bundle.wand import calibrate_on_control
from kisscal.camera import Camera
from kisscal.detect import DetectionParams
from kisscal.detect.configure import DERIVED
from kisscal.dlt import DltParams, calibrate_camera
from kisscal.dlt.nonlinear import refine_dlt
from kisscal.errors import KisscalError
from kisscal.io.config import load_session
from kisscal.session.params import MEMBERS, stage_params
from kisscal.session.runner import markers_detection, trial_blobs
from kisscal.synth.scene import rod_set
from tests.bundle.conftest import WandScene, scene


def _base(tmp: Path) -> dict[str, Any]:
    """The smallest session every table can be added to (no file is read)."""
    return {
        "session": {"name": "every", "rate_hz": 50.0},
        "cameras": [{"id": "cam1", "size": [200, 150]}, {"id": "cam2", "size": [200, 150]}],
        "trials": [{"name": "wave", "centroids": "wave/{camera}.csv"}],
        "grid": {"rows": 15, "cols": 20, "images": "grid/{camera}/*.png"},
        "wand": {"trial": "wave", "markers_mm": [0.0, 500.0]},
    }


def _numbers(default: float, kind: type) -> list[float]:
    """Numbers near ``default`` (and a few plain ones) to try as non-default values."""
    if kind is int:
        return [default + 1, default + 2, default - 1, 2 * default, 3, 5, 7, 9]
    return [default * 1.5, default * 0.5, default + 0.1, default - 0.1, 0.5, 0.05, 2.0, 1.5]


def _candidates(member: str, f: dataclasses.Field, hint: Any) -> list[Any]:
    """Values of one field to try, other than its default."""
    default = f.default
    args = [a for a in typing.get_args(hint) if a is not type(None)]
    meta = f.metadata.get("kisscal", {})
    kind = args[0] if default is None and args else hint
    if meta.get("choices"):
        return list(meta["choices"])
    if typing.get_origin(kind) is Literal:
        return list(typing.get_args(kind))
    if kind is bool:
        return [not default]
    if kind in (int, float):
        return [kind(v) for v in _numbers(default if default is not None else 10, kind)]
    if typing.get_origin(kind) is tuple:
        element = typing.get_args(kind)[0]
        if typing.get_origin(element) is Literal:
            return [tuple(typing.get_args(element)[:n]) for n in (1, 2, 3)]
        if element is str:  # names (of trials)
            return [("walk01",), ("walk01", "stick")]
        base = default if default is not None else (3, 3)
        return [tuple(element(v) for v in vs) for vs in _scaled(base, element)]
    raise AssertionError(f"no candidate values for {member}.{f.name} ({hint})")


def _scaled(base: tuple, element: type) -> list[tuple]:
    """Tuples like ``base``: each element moved the same way."""
    if element is int:
        return [tuple(v + d for v in base) for d in (2, 4, -2)]
    return [tuple(v * s for v in base) for s in (0.5, 1.5)] + [tuple(v + 1 for v in base)]


def _set_value(cls: type, member: str, f: dataclasses.Field) -> Any:
    """A valid value of the field other than its default, as the class holds it."""
    hint = typing.get_type_hints(cls)[f.name]
    for value in _candidates(member, f, hint):
        try:
            held = getattr(cls(**{f.name: value}), f.name)
        except (KisscalError, TypeError, ValueError):
            continue
        if held != f.default:
            return held
    raise AssertionError(f"no valid non-default value found for {member}.{f.name}")


def _fields() -> list[tuple[str, type, dataclasses.Field]]:
    return [(member, cls, f) for member, cls in MEMBERS.items() for f in dataclasses.fields(cls)]


FIELDS = _fields()


def _toml(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


def test_the_walk_covers_every_stage() -> None:
    """Nine parameter classes, every one of their fields (205 today)."""
    counts = {m: sum(1 for mm, _c, _f in FIELDS if mm == m) for m in MEMBERS}
    assert set(counts) == {
        "detection", "grid", "dlt", "recon", "tracking", "gait", "wand", "target", "report",
    }  # fmt: skip
    assert all(n >= 7 for n in counts.values()), counts
    assert len(FIELDS) == sum(len(dataclasses.fields(c)) for c in MEMBERS.values())


@pytest.mark.parametrize(
    ("member", "cls", "f"), FIELDS, ids=[f"{m}.{f.name}" for m, _c, f in FIELDS]
)
def test_a_setting_in_session_toml_reaches_the_stage(
    member: str, cls: type, f: dataclasses.Field, tmp_path: Path
) -> None:
    value = _set_value(cls, member, f)
    data = _base(tmp_path)
    data.setdefault(cls.section, {})[f.name] = _toml(value)
    (tmp_path / "session.toml").write_text(tomli_w.dumps(data))
    resolved = getattr(stage_params(load_session(tmp_path)), member)
    assert getattr(resolved, f.name) == value != f.default
    others = {g.name for g in dataclasses.fields(cls)} - {f.name}
    defaults = cls()
    changed = [n for n in others if getattr(resolved, n) != getattr(defaults, n)]
    if member != "grid":  # [grid] rows and cols always come from the table's own keys
        assert not changed, f"setting {f.name} changed {changed}"


@pytest.mark.parametrize(
    ("section", "key", "value", "says"),
    [
        ("recon", "allow_two_camera", "no", "true or false"),
        ("recon", "max_candidates", 2.5, "a whole number"),
        ("recon", "max_rms_px", True, "a finite number"),
        ("tracking", "smoothing", "yes", "true or false"),
        ("tracking", "gate_m", [0.6, 0.6], "3 floats"),
    ],
)
def test_a_value_of_the_wrong_kind_is_refused(
    section: str, key: str, value: Any, says: str, tmp_path: Path
) -> None:
    """Every table is checked by the one validator: before, [recon] and [tracking] took
    ``"no"`` for true and 2.5 for a count."""
    data = _base(tmp_path)
    data[section] = {key: value}
    (tmp_path / "session.toml").write_text(tomli_w.dumps(data))
    with pytest.raises(KisscalError, match=rf"^\[{section}\] {key} must be {says}, got"):
        stage_params(load_session(tmp_path))


# ---------------------------------------------------------------- through the survey


def _marker_session(root: Path, detection: dict[str, Any]) -> Path:
    """Two cameras' frames of six round markers, three bright and three faint (grey
    levels 230 and 90 over a background of 20), with mild noise."""
    rng = np.random.default_rng(5)
    for cam in ("cam1", "cam2"):
        folder = root / "trials" / "walk" / cam
        folder.mkdir(parents=True)
        for k in range(4):
            image = np.full((150, 200), 20.0)
            for i, level in enumerate((230, 230, 230, 90, 90, 90)):
                centre = (30 + 28 * i + k, 50 + 10 * (i % 2) + 2 * k)
                cv2.circle(image, centre, 3, level, -1)
            image += rng.normal(0, 1.5, image.shape)
            cv2.imwrite(str(folder / f"{k:04d}.png"), np.clip(image, 0, 255).astype(np.uint8))
    data = {
        "session": {"name": "markers", "rate_hz": 50.0},
        "cameras": [{"id": "cam1", "size": [200, 150]}, {"id": "cam2", "size": [200, 150]}],
        "trials": [{"name": "walk", "images": "trials/walk/{camera}/*.png"}],
    }
    if detection:
        data["detection"] = detection
    (root / "session.toml").write_text(tomli_w.dumps(data))
    return root


@pytest.fixture(scope="module")
def derived(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The settings the survey derives for camera 1 with nothing given."""
    root = _marker_session(tmp_path_factory.mktemp("derived"), {})
    config = load_session(root)
    params = markers_detection(config, stage_params(config), workers=1)["cam1"]
    return {name: getattr(params, name) for name in DERIVED}


def _other_than(name: str, derived: Any) -> Any:
    """A valid value of a derived setting other than the one derived."""
    if name == "detach_kernel_px":
        return (7, 5) if derived != (7, 5) else (9, 7)
    if name == "threshold":
        return 150.0
    if name in ("pixel_aspect",):
        return 1.25
    return (derived or 20) + 2


DETECTION = [f for m, _c, f in FIELDS if m == "detection"]


@pytest.mark.parametrize("f", DETECTION, ids=[f.name for f in DETECTION])
def test_a_detection_setting_given_is_what_each_camera_detects_with(
    f: dataclasses.Field, derived: dict[str, Any], tmp_path: Path
) -> None:
    """Through the survey, which derives some settings per camera (:data:`DERIVED`):
    a value given in ``[detection]`` is the one the camera's detection receives."""
    name = f.name
    if name in DERIVED:
        value, before = _other_than(name, derived[name]), derived[name]
    else:
        value, before = _set_value(DetectionParams, "detection", f), f.default
    root = _marker_session(tmp_path, {name: _toml(value)})
    config = load_session(root)
    got = markers_detection(config, stage_params(config), workers=1)
    assert all(getattr(p, name) == value != before for p in got.values())
    kept = markers_detection(config, stage_params(config), workers=1)  # read back
    assert kept == got


def test_the_threshold_given_changes_what_is_detected(tmp_path: Path) -> None:
    """End to end: a threshold between the faint and the bright markers keeps the
    bright ones only; derived, the threshold keeps all six."""
    counts = {}
    for given in ({}, {"threshold": 150}):
        root = _marker_session(tmp_path / str(len(given)), given)
        config = load_session(root)
        params = stage_params(config)
        detection = markers_detection(config, params, workers=1)
        trial = config.trial("walk")
        blobs = trial_blobs(config, trial, detection, lambda _s: None, workers=1)
        counts[len(given)] = {len(b) for b in blobs["cam1"]}
    assert counts == {0: {6}, 1: {3}}


def test_the_grid_lattice_aspect_reaches_the_marker_detection(
    small_session: Path, tmp_path: Path
) -> None:
    """A camera with a grid: its marker settings take the pixel aspect its grid's dot
    lattice gives (handed over in memory, not read back from the file being written),
    and the file records both kinds."""
    root = tmp_path / "s"
    root.mkdir()
    for part in ("grid", "trials", "rods", "session.toml"):
        copy = shutil.copytree if (small_session / part).is_dir() else shutil.copy
        copy(small_session / part, root / part)
    config = load_session(root)
    cam = config.cameras[0]
    params = markers_detection(config, stage_params(config), cameras=[cam], workers=1)
    doc = json.loads((root / "out" / "detection" / f"{cam.id}.json").read_text())
    grid = doc["kinds"]["grid"]["settings"]["pixel_aspect"]
    assert grid["source"] == "derived" and abs(grid["value"] - 1.0) > 0.5  # 752 x 291 fields
    assert params[cam.id].pixel_aspect == grid["value"]
    assert doc["kinds"]["markers"]["settings"]["pixel_aspect"]["value"] == grid["value"]


def test_the_dlt_settings_reach_the_resected_cameras(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """End to end from ``session.toml``: ``[dlt]``'s convergence tolerance reaches the
    fits of the cameras a wand calibration on a grid writes resected
    (:func:`kisscal.bundle.resect.final_cameras`, which fitted with the default DLT
    settings whatever the session said; the route now hands it the session's). Since
    those fits start from the adjusted pinhole, a loose tolerance no longer shows in the
    cameras (0.0227 against 0.0233 px): the settings each fit is given are recorded."""
    data = _base(tmp_path)
    data["dlt"] = {"tolerance": 0.5}
    (tmp_path / "session.toml").write_text(tomli_w.dumps(data))
    loose = stage_params(load_session(tmp_path)).dlt
    assert loose.tolerance == 0.5
    given: list[float] = []

    def recording(xyz, uv, start, params, **kw):
        given.append(params.tolerance)
        return refine_dlt(xyz, uv, start, params, **kw)

    monkeypatch.setattr(resect, "refine_dlt", recording)
    s = scene(2, 60)
    rig = tuple(Camera(c.K, c.R, c.t, 0.1 * c.lens, c.id, c.size_px) for c in s.rig)
    pts = np.concatenate([r.points_mm for r in rod_set(2)])
    cams = np.repeat(np.arange(len(rig)), len(pts))
    uv = np.concatenate([c.project(pts) for c in rig])
    control = ControlPoints(cams, np.tile(pts, (len(rig), 1)), uv, cams * 0)
    starts = [Camera.from_dlt(calibrate_camera(pts, uv[cams == c]).L) for c in range(len(rig))]
    table = WandScene(rig, s.motion, s.markers_mm).blobs(ideal=False, noise_px=0.05)
    args = (table, starts, control, s.markers_mm, s.sizes, s.ids, "w")
    on_grid = BundleParams(control_weight=1.0).on_grid()
    for dlt in (DltParams(), loose):
        given.clear()
        cal = calibrate_on_control(*args, on_grid, dlt)
        assert cal.resected is not None and cal.dlt == dlt  # refits resect with it too
        assert given and set(given) == {dlt.tolerance}, given
