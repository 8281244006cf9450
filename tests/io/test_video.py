"""Videos: one sequential reader per camera, any access order, and interlaced frames split
into fields exactly as the field images of the same session."""

from __future__ import annotations

import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
import tomli_w

from kisscal.io.config import load_toml
from kisscal.io.frames import Fields, VideoFrames, camera_frames, read_image


def write_video(path: Path, frames: list[np.ndarray], rate: float = 25.0) -> Path:
    """A lossless (FFV1) grey video."""
    h, w = frames[0].shape
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), rate, (w, h), False)
    assert writer.isOpened()
    for f in frames:
        writer.write(f)
    writer.release()
    return path


def interlace(top: np.ndarray, bottom: np.ndarray) -> np.ndarray:
    frame = np.empty((top.shape[0] + bottom.shape[0], top.shape[1]), top.dtype)
    frame[0::2], frame[1::2] = top, bottom
    return frame


def test_frames_in_any_order_are_the_frames_written(tmp_path):
    rng = np.random.default_rng(0)
    frames = [rng.integers(0, 256, (48, 64), dtype=np.uint8) for _ in range(90)]
    video = VideoFrames(write_video(tmp_path / "v.avi", frames))
    assert len(video) == 90
    order = [*range(90), 89, 3, 4, 80, 81, 10, 75, 0]  # in order, back, far forward
    for k in order:
        np.testing.assert_array_equal(video[k], frames[k])
    with pytest.raises(IndexError):
        video[90]


@pytest.mark.parametrize("order", ["top-first", "bottom-first"])
def test_fields_of_interlaced_frames(tmp_path, order):
    rng = np.random.default_rng(1)
    fields = [rng.integers(0, 256, (29, 64), dtype=np.uint8) for _ in range(10)]
    pairs = zip(fields[0::2], fields[1::2], strict=True)
    frames = [interlace(a, b) if order == "top-first" else interlace(b, a) for a, b in pairs]
    split = Fields(VideoFrames(write_video(tmp_path / "v.avi", frames)), order)
    assert len(split) == 10
    for k in range(10):
        np.testing.assert_array_equal(split[k], fields[k])


def test_interlaced_video_session_gives_the_png_sessions_points(small_session, tmp_path):
    """The walk of the synthetic session as one interlaced video per camera (two fields
    per frame, top field first): the same fields, hence the same 3D points."""
    from kisscal import session
    from kisscal.io.files import read_table

    root = tmp_path / "video"
    shutil.copytree(small_session, root, ignore=shutil.ignore_patterns("out"))
    config = load_toml(root / "session.toml")
    walk = next(t for t in config["trials"] if t["name"] == "walk01")
    (root / "video").mkdir()
    for cam in [c["id"] for c in config["cameras"]]:
        pngs = sorted((root / "trials" / "walk01" / cam).glob("*.png"))
        images = [read_image(p) for p in pngs[:24]]
        frames = [interlace(a, b) for a, b in zip(images[0::2], images[1::2], strict=True)]
        video = write_video(root / "video" / f"{cam}.avi", frames)
        split = camera_frames(root, "video/{camera}.avi", cam, "trial", fields="top-first")
        assert len(split) == len(images) and str(video).endswith(".avi")
        for k in (0, 1, 7, 23):
            np.testing.assert_array_equal(split[k], images[k])
        for p in pngs[24:]:
            p.unlink()  # the PNG trial: the same 24 fields
    config["trials"] = [
        {"name": "png", "images": walk["images"]},
        {"name": "vid", "video": "video/{camera}.avi", "fields": "top-first"},
    ]
    (root / "session.toml").write_text(tomli_w.dumps(config))
    session.calibrate(root, workers=2)
    for trial in ("png", "vid"):
        session.reconstruct(root, trial, workers=2)
    png = read_table(root / "out" / "trials" / "png" / "points3d.csv")
    vid = read_table(root / "out" / "trials" / "vid" / "points3d.csv")
    assert len(png["field"]) > 100
    for key in ("field", "x_mm", "y_mm", "z_mm", "rms_px"):
        np.testing.assert_array_equal(vid[key], png[key])


def test_any_image_set_may_be_a_video(tmp_path):
    """A grid or rod pattern ending in a video suffix reads the camera's video."""
    rng = np.random.default_rng(2)
    frames = [rng.integers(0, 256, (20, 30), dtype=np.uint8) for _ in range(4)]
    (tmp_path / "grid").mkdir()
    write_video(tmp_path / "grid" / "cam1.avi", frames)
    grid = camera_frames(tmp_path, "grid/{camera}.avi", "cam1", "grid")
    assert isinstance(grid, VideoFrames) and len(grid) == 4
    np.testing.assert_array_equal(grid[3], frames[3])
    fields = camera_frames(tmp_path, "grid/{camera}.avi", "cam1", "grid", fields="bottom-first")
    np.testing.assert_array_equal(fields[0], frames[0][1::2])
