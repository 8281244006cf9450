"""Frames named as particle-tracking and camera tools name them: numbered, no suffix."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

import kisscal.io.frames as frames_module
from kisscal.errors import KisscalError
from kisscal.io.frames import camera_frames, frame_paths, is_image_file, listing_once

REAL = Path(__file__).resolve().parents[2] / "fixtures" / "real" / "openptv-cavity"


def _numbered(folder: Path) -> np.ndarray:
    """Real frames (the cavity photograph crop) as OpenPTV names them, beside its files."""
    image = cv2.imread(str(REAL / "target_cam1_crop.png"), cv2.IMREAD_GRAYSCALE)
    folder.mkdir()
    for i, ext in enumerate((".tif", ".png", ".bmp")):
        data = cv2.imencode(ext, np.roll(image, i, axis=1))[1].tobytes()
        (folder / f"cam1.{10000 + i}").write_bytes(data)
    (folder / "cam1.10000_targets").write_text("3\n1 2 3\n")  # a text file: not a frame
    (folder / "cam1.tif.ori").write_text("0 0 0\n")
    return image


def test_frames_without_a_suffix_are_read_by_content(tmp_path: Path) -> None:
    image = _numbered(tmp_path / "img")
    paths = frame_paths(tmp_path, "img/{camera}.*", "cam1", "trial")
    assert [p.name for p in paths] == ["cam1.10000", "cam1.10001", "cam1.10002"]
    frames = camera_frames(tmp_path, "img/{camera}.*", "cam1", "trial")
    for i in range(3):
        assert np.array_equal(frames[i], np.roll(image, i, axis=1))
    assert not is_image_file(tmp_path / "img" / "cam1.10000_targets")


def test_a_pattern_that_misses_names_the_files_it_missed(tmp_path: Path) -> None:
    _numbered(tmp_path / "img")
    with pytest.raises(KisscalError) as caught:
        frame_paths(tmp_path, "img/{camera}.tif", "cam1", "trial")
    message = str(caught.value)
    assert "img/cam1.tif" in message and "cam1.10000" in message and '"{camera}.*"' in message
    with pytest.raises(KisscalError, match=r"matches .*cam1.10000_targets.* none a PNG"):
        frame_paths(tmp_path, "img/{camera}.*_targets", "cam1", "trial")
    with pytest.raises(KisscalError, match="there is no folder"):
        frame_paths(tmp_path, "nowhere/{camera}/*.png", "cam1", "trial")


def test_a_run_lists_each_folder_once(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Inside ``listing_once`` (``kisscal run``) a camera's folder is globbed once and the
    same files come back each time; outside it every call lists anew."""
    _numbered(tmp_path / "img")
    globs = []
    real_glob = frames_module._glob
    monkeypatch.setattr(frames_module, "_glob", lambda *a: globs.append(a) or real_glob(*a))
    with listing_once():
        first = frame_paths(tmp_path, "img/{camera}.*", "cam1", "trial")
        (tmp_path / "img" / "cam1.10003.png").write_bytes(b"")  # not seen: listed once
        again = [frame_paths(tmp_path, "img/{camera}.*", "cam1", "trial") for _ in range(3)]
        assert all(paths == first for paths in again) and len(globs) == 1
        again[0].clear()  # a caller's list is its own
        assert frame_paths(tmp_path, "img/{camera}.*", "cam1", "trial") == first
    assert len(frame_paths(tmp_path, "img/{camera}.*", "cam1", "trial")) == len(first) + 1
    assert len(globs) == 2
