"""The known-target route on a real rig: OpenPTV's cavity target (fixtures/real/openptv-cavity).

Four cameras behind a glass wall looking into water with long lenses (focal length about
7000-9000 px on a 1280 px sensor); two of them see only a near-flat part of the target.
OpenPTV's own calibration (with refraction) is the peer: kisscal's cameras must
reproject the target points at least as well, from four clicked seeds.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from kisscal import session
from kisscal._shared import rms_px
from kisscal.errors import KisscalError
from kisscal.session.validate import validate
from kisscal.target.dots import find_target_dots
from kisscal.target.match import match_target
from kisscal.target.resect import model_name
from tests.target.cavity import CAMERAS, FIXTURES, SIZE_PX, spread_seeds, target_xyz, view
from tests.target.openptv import project as openptv_project

#: Where ``target_cam1_crop.png`` lies in cam1's 1280 x 1024 photograph (u, v of its corner).
CROP_ORIGIN = (193, 295)


@pytest.mark.parametrize("camera", CAMERAS)
def test_openptv_model_lands_on_its_own_detections(camera: str) -> None:
    """The peer is read right: OpenPTV's projection within 2 px of its detections (how
    ``camN_dots.csv`` was built) and unbiased (the half-pixel origin shift is right)."""
    v = view(FIXTURES, camera)
    res = openptv_project(v.openptv, v.xyz_mm) - v.uv_px
    assert np.linalg.norm(res, axis=1).max() < 2.0
    assert np.all(np.abs(res.mean(axis=0)) < 0.35)


@pytest.mark.parametrize(
    ("camera", "n_seeds"),
    [*((c, 4) for c in CAMERAS), ("cam1", 6), ("cam4", 6)],
)
def test_every_camera_calibrates_from_few_seeds(camera: str, n_seeds: int) -> None:
    """From 4 or 6 clicks every point OpenPTV detected is matched to its own detection,
    and the camera reprojects them better than OpenPTV's calibration does."""
    v = view(FIXTURES, camera)
    seeds = spread_seeds(v, n_seeds)
    m = match_target(
        target_xyz(FIXTURES), v.uv_px[seeds], v.xyz_mm[seeds], v.uv_px, SIZE_PX, camera
    )
    matched = np.flatnonzero(m.matched)
    assert len(matched) >= 0.95 * len(v.ids)
    assert np.array_equal(v.ids[m.dot[matched]], matched + 1)  # each to its own detection
    peer = rms_px(openptv_project(v.openptv, v.xyz_mm) - v.uv_px)
    assert m.rms_px < min(0.7, peer)
    assert m.held_out_px[model_name(m.terms)] <= m.held_out_px["pinhole"]


def _cam1_dots() -> np.ndarray:
    crop = cv2.imread(str(FIXTURES / "target_cam1_crop.png"), cv2.IMREAD_GRAYSCALE)
    v = view(FIXTURES, "cam1")
    seeds = v.uv_px[spread_seeds(v, 4)] - CROP_ORIGIN
    return find_target_dots(crop, seeds) + CROP_ORIGIN


def test_real_photograph_dots_match_openptvs_detections() -> None:
    """Dots found in the real photograph (specks and glare included) from 4 seeds: the
    long-lens, near-flat view matches nearly every point, none to a wrong dot."""
    v = view(FIXTURES, "cam1")
    dots = _cam1_dots()
    seeds = spread_seeds(v, 4)
    m = match_target(target_xyz(FIXTURES), v.uv_px[seeds], v.xyz_mm[seeds], dots, SIZE_PX, "cam1")
    ref = np.full((73, 2), np.nan)
    ref[v.ids - 1] = v.uv_px
    both = m.matched & np.isfinite(ref[:, 0])
    assert both.sum() >= 0.85 * len(v.ids)
    assert np.linalg.norm(dots[m.dot[both]] - ref[both], axis=1).max() < 2.0
    assert m.rms_px < 0.6


def test_near_flat_seeds_that_fix_no_camera_are_refused_with_the_cause() -> None:
    """Three seeds on one row and one on another (one plane) under a narrow view fit
    cameras from a wide to a long lens alike: refused, naming that, never a traceback or
    a wrong calibration."""
    v = view(FIXTURES, "cam1")
    picked = [(0, 25, 8), (-40, 0, -8), (-35, 0, -8), (10, 0, -8)]
    seeds = [int(np.flatnonzero(np.all(v.xyz_mm == p, axis=1))[0]) for p in picked]
    with pytest.raises(KisscalError, match=r"nearly in one plane .* three or more rows"):
        match_target(
            target_xyz(FIXTURES), v.uv_px[seeds], v.xyz_mm[seeds], _cam1_dots(), SIZE_PX, "cam1"
        )


def _cam1_session(root: Path, n_seeds: int) -> Path:
    """A one-camera target session: the real crop put back into a full-size frame."""
    root.mkdir(parents=True)
    crop = cv2.imread(str(FIXTURES / "target_cam1_crop.png"), cv2.IMREAD_GRAYSCALE)
    frame = np.zeros(SIZE_PX[::-1], np.uint8)
    u0, v0 = CROP_ORIGIN
    frame[v0 : v0 + crop.shape[0], u0 : u0 + crop.shape[1]] = crop
    (root / "cal").mkdir()
    (root / "cal" / "cam1.10000").write_bytes(cv2.imencode(".tif", frame)[1].tobytes())
    xyz = target_xyz(FIXTURES)
    rows = ["x_mm,y_mm,z_mm", *(f"{x:g},{y:g},{z:g}" for x, y, z in xyz)]
    (root / "target.csv").write_text("\n".join(rows) + "\n")
    v = view(FIXTURES, "cam1")
    seeds = ["u_px,v_px,x_mm,y_mm,z_mm"] + [
        ",".join(f"{a:g}" for a in (*v.uv_px[i], *v.xyz_mm[i])) for i in spread_seeds(v, n_seeds)
    ]
    (root / "cam1_seeds.csv").write_text("\n".join(seeds) + "\n")
    (root / "session.toml").write_text(
        '[session]\nname = "cavity"\nrate_hz = 100\n\n[[cameras]]\nid = "cam1"\n\n'
        '[calibration]\ntarget = "target.csv"\nimages = "cal/{camera}.*"\n'
        'seeds = "{camera}_seeds.csv"\n'
    )
    return root


def test_four_seeds_pass_validate_and_calibrate(tmp_path: Path) -> None:
    """A real photograph named without a suffix, 4 seeds: validate and calibrate agree."""
    root = _cam1_session(tmp_path / "s4", 4)
    assert validate(root) == []
    session.calibrate(root)
    written = (root / "out" / "dlt" / "cam1.json").read_text()
    assert '"method": "target"' in written


def test_three_seeds_are_refused_by_validate_and_calibrate_alike(tmp_path: Path) -> None:
    root = _cam1_session(tmp_path / "s3", 3)
    problems = [str(p) for p in validate(root)]
    assert len(problems) == 1 and "3 seeds; click at least 4" in problems[0]
    with pytest.raises(KisscalError, match="3 seeds; click at least 4") as caught:
        session.calibrate(root)
    assert problems[0].endswith(str(caught.value).split(": ", 1)[1])


def test_seed_lines_off_the_image_are_no_clicks_to_validate_and_calibrate_alike(
    tmp_path: Path,
) -> None:
    """MyPTV writes ``-1, -1`` for a target point it was not given a click for: such a
    line is left out (the log names it), and does not count as a seed."""
    unclicked = "-1,-1,0,0,0\n"
    four = _cam1_session(tmp_path / "s4", 4)
    seeds = four / "cam1_seeds.csv"
    seeds.write_text(seeds.read_text() + unclicked)
    assert validate(four) == []
    said: list[str] = []
    session.calibrate(four, echo=said.append)
    assert any("seed line 6 of cam1_seeds.csv lies outside" in line for line in said), said
    three = _cam1_session(tmp_path / "s3", 3)
    seeds = three / "cam1_seeds.csv"
    seeds.write_text(seeds.read_text() + unclicked)
    problems = [str(p) for p in validate(three)]
    assert len(problems) == 1 and "3 seeds; click at least 4" in problems[0]
    with pytest.raises(KisscalError, match="3 seeds; click at least 4"):
        session.calibrate(three)


def test_points_route_needs_no_size_without_images(tmp_path: Path) -> None:
    """[calibration] points and no [[cameras]] size: the DLT of each camera's real
    points, as close to them as OpenPTV's calibration with refraction."""
    cams = "".join(f'[[cameras]]\nid = "{c}"\n\n' for c in CAMERAS)
    (tmp_path / "session.toml").write_text(
        '[session]\nname = "cavity"\nrate_hz = 100\n\n'
        + cams
        + '[calibration]\npoints = "{camera}.csv"\n'
    )
    for cam in CAMERAS:
        v = view(FIXTURES, cam)
        table = np.column_stack([v.uv_px, v.xyz_mm])
        rows = ["u_px,v_px,x_mm,y_mm,z_mm"] + [",".join(f"{a:g}" for a in r) for r in table]
        (tmp_path / f"{cam}.csv").write_text("\n".join(rows) + "\n")
    result = session.calibrate(tmp_path)
    for cam in CAMERAS:
        v = view(FIXTURES, cam)
        peer = rms_px(openptv_project(v.openptv, v.xyz_mm) - v.uv_px)
        assert result[cam].rms_px < peer
