"""session.toml validation: every error names the file, the key and what was expected."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import tomli_w

from kisscal.errors import KisscalError
from kisscal.io.config import load_session, load_toml
from kisscal.io.frames import read_image, trial_frames


def edited(small_session: Path, tmp_path: Path, edit) -> Path:
    root = tmp_path / "s"
    root.mkdir()
    data = load_toml(small_session / "session.toml")
    edit(data)
    (root / "session.toml").write_text(tomli_w.dumps(data))
    return root


def test_synthetic_session_loads(small_session: Path) -> None:
    config = load_session(small_session)
    assert config.camera_ids == tuple(f"cam{i}" for i in range(1, 7))
    assert config.grid is not None and (config.grid.rows, config.grid.cols) == (15, 20)
    assert [r.points_mm.shape for r in config.rods.rods] == [(6, 3)] * 4
    assert config.trial("walk01").source == "images"


def test_unknown_key_suggests_the_right_one(small_session: Path, tmp_path: Path) -> None:
    root = edited(small_session, tmp_path, lambda d: d["session"].update(rate_hzz=50))
    with pytest.raises(
        KisscalError, match=r"session.toml: unknown key session.'rate_hzz'.*'rate_hz'"
    ):
        load_session(root)


def test_missing_key_is_named(small_session: Path, tmp_path: Path) -> None:
    root = edited(small_session, tmp_path, lambda d: d["session"].pop("rate_hz"))
    with pytest.raises(KisscalError, match=r"missing key session.'rate_hz'"):
        load_session(root)


def _resolved(root: Path):
    """The session's resolved parameters (where [rods] are checked against [dlt])."""
    from kisscal import session

    return session.stage_params(load_session(root))


def _flatten(d: dict) -> None:
    for rod in d["rods"]["rod"]:
        for p in rod["points_mm"]:
            p[1] = 0.0  # every rod in the plane y = 0


def test_coplanar_rods_are_refused(small_session: Path, tmp_path: Path) -> None:
    with pytest.raises(KisscalError, match="coplanar"):
        _resolved(edited(small_session, tmp_path, _flatten))


def test_rods_are_checked_against_the_sessions_dlt_limits(
    small_session: Path, tmp_path: Path
) -> None:
    """[dlt] min_spread_ratio and min_points decide, not their defaults."""

    def nearly_flat(d: dict) -> None:
        _flatten(d)
        d["rods"]["rod"][0]["points_mm"][0][1] = 5.0  # one marker 5 mm off the plane

    root = edited(small_session, tmp_path, nearly_flat)
    with pytest.raises(KisscalError, match="coplanar"):  # a spread ratio under 1e-3
        _resolved(root)
    (root / "session.toml").write_text(
        (root / "session.toml").read_text() + "\n[dlt]\nmin_spread_ratio = 1e-6\n"
    )
    assert _resolved(root).dlt.min_spread_ratio == 1e-6  # accepted under the looser limit
    (root / "session.toml").write_text((root / "session.toml").read_text() + "min_points = 25\n")
    with pytest.raises(KisscalError, match=r"gives 24 points; .*at least 25 \(\[dlt\] min_points"):
        _resolved(root)


def test_too_few_rod_points(small_session: Path, tmp_path: Path) -> None:
    def shrink(d: dict) -> None:
        d["rods"]["rod"] = d["rods"]["rod"][:1]
        d["rods"]["rod"][0]["points_mm"] = d["rods"]["rod"][0]["points_mm"][:5]

    with pytest.raises(KisscalError, match="at least 6"):
        _resolved(edited(small_session, tmp_path, shrink))


def test_unknown_trial_is_named(small_session: Path) -> None:
    with pytest.raises(KisscalError, match=r"no trial named 'walk1'.*did you mean 'walk01'"):
        load_session(small_session).trial("walk1")


def test_unequal_frame_counts(small_session: Path, tmp_path: Path) -> None:
    root = tmp_path / "copy"
    shutil.copytree(small_session / "trials" / "throw", root / "trials" / "throw")
    next(iter(sorted((root / "trials" / "throw" / "cam2").glob("*.png")))).unlink()
    with pytest.raises(KisscalError, match=r"different numbers of frames.*cam2: 45"):
        trial_frames(root, "trials/throw/{camera}/*.png", ["cam1", "cam2"], "throw")


def test_corrupt_png_is_named(tmp_path: Path) -> None:
    bad = tmp_path / "000001.png"
    bad.write_bytes(b"\x89PNG\r\n\x1a\n" + b"garbage" * 10)
    with pytest.raises(KisscalError, match=r"000001.png: not a readable image"):
        read_image(bad)


def test_missing_camera_folder(small_session: Path) -> None:
    with pytest.raises(KisscalError, match="no trial 'walk01' images for camera cam9"):
        trial_frames(small_session, "trials/walk01/{camera}/*.png", ["cam1", "cam9"], "walk01")


# BMP holds no 16-bit grey: that pair is not a case, not a skipped test
FORMATS = [
    (suffix, dtype)
    for suffix in (".tif", ".bmp", ".png")
    for dtype in ("uint8", "uint16", "bool")
    if (suffix, dtype) != (".bmp", "uint16")
]


@pytest.mark.parametrize(("suffix", "dtype"), FORMATS)
def test_frame_formats(tmp_path: Path, suffix: str, dtype: str) -> None:
    """PNG and TIFF frames, 8- or 16-bit or binary, and BMP 8-bit or binary, read back as
    grey images."""
    import cv2
    import numpy as np

    rng = np.random.default_rng(0)
    grey = rng.integers(0, 255, (29, 75)).astype(np.uint8)
    if dtype == "uint16":
        data = grey.astype(np.uint16) * 257
    elif dtype == "bool":
        data = np.where(grey > 128, 255, 0).astype(np.uint8)
    else:
        data = grey
    path = tmp_path / f"frame{suffix}"
    assert cv2.imwrite(str(path), data)
    image = read_image(path)
    assert image.shape == (29, 75) and image.dtype == data.dtype
    np.testing.assert_array_equal(image, data)


def test_grid_and_stage_sections_reach_the_stages(small_session: Path, tmp_path: Path) -> None:
    from kisscal import session

    def tune(d: dict) -> None:
        d["grid"]["model"] = "similarity"
        d["tracking"] = {"pnc": 0.05}
        d["recon"] = {"strategy": "central"}

    params = session.stage_params(load_session(edited(small_session, tmp_path, tune)))
    assert params.grid.model == "similarity" and params.grid.rows == 15
    assert params.tracking.pnc == 0.05 and params.recon.strategy == "central"


@pytest.mark.parametrize(
    ("section", "key", "hint"),
    [("grid", "modle", "model"), ("tracking", "pcn", "pnc"), ("dlt", "mldt", "mdlt")],
)
def test_misspelt_stage_parameter(
    small_session: Path, tmp_path: Path, section: str, key: str, hint: str
) -> None:
    from kisscal import session

    root = edited(small_session, tmp_path, lambda d: d.setdefault(section, {}).update({key: 1}))
    with pytest.raises(KisscalError, match=rf"\[{section}\] unknown parameter '{key}'.*'{hint}'"):
        session.stage_params(load_session(root))
