"""Bad inputs give one clear line and a non-zero exit; earlier good outputs survive."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import tomli_w

from kisscal.io.config import load_toml

pytestmark = pytest.mark.slow


@pytest.fixture
def good(processed: Path) -> Path:
    """The processed seed-7 session (four cameras, 20 fields) of conftest.py."""
    return processed


def kisscal(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "kisscal", *args], capture_output=True, text=True, timeout=600
    )


def copy(good: Path, tmp_path: Path) -> Path:
    root = tmp_path / "s"
    shutil.copytree(good, root)
    return root


def error_lines(result: subprocess.CompletedProcess[str]) -> list[str]:
    """The error lines of a command's stderr (the log before them says what was done);
    the one error line is the last line."""
    lines = result.stderr.strip().splitlines()
    errors = [line for line in lines if ": error: " in line]
    assert errors and errors[-1] == lines[-1] and "Traceback" not in result.stderr, result.stderr
    return errors


def assert_one_line_error(result: subprocess.CompletedProcess[str], *words: str) -> None:
    assert result.returncode == 2, result.stdout + result.stderr
    lines = error_lines(result)
    assert len(lines) == 1, result.stderr
    for w in words:
        assert w in lines[0], lines[0]


def test_corrupt_png(good: Path, tmp_path: Path) -> None:
    root = copy(good, tmp_path)
    before = (root / "out" / "trials" / "walk01" / "points3d.csv").read_bytes()
    (root / "trials" / "walk01" / "cam2" / "000005.png").write_bytes(b"\x89PNG\r\n\x1a\nbroken")
    result = kisscal("run", str(root))
    assert_one_line_error(result, "000005.png", "not a readable image")
    assert (root / "out" / "trials" / "walk01" / "points3d.csv").read_bytes() == before


def test_missing_frame_in_one_camera(good: Path, tmp_path: Path) -> None:
    root = copy(good, tmp_path)
    before = (root / "out" / "trials" / "walk01" / "trajectories.csv").read_bytes()
    (root / "trials" / "walk01" / "cam3" / "000007.png").unlink()
    result = kisscal("reconstruct", str(root), "walk01")
    assert_one_line_error(result, "walk01", "different numbers of frames", "cam3: 19")
    assert (root / "out" / "trials" / "walk01" / "trajectories.csv").read_bytes() == before


def test_rod_missing_from_config(good: Path, tmp_path: Path) -> None:
    root = copy(good, tmp_path)
    before = (root / "out" / "dlt" / "cam1.json").read_bytes()
    data = load_toml(root / "session.toml")
    data["rods"]["rod"] = data["rods"]["rod"][:3]
    (root / "session.toml").write_text(tomli_w.dumps(data))
    result = kisscal("calibrate", str(root))
    assert result.returncode != 0 and len(error_lines(result)) == 1
    assert (root / "out" / "dlt" / "cam1.json").read_bytes() == before


def test_truncated_video(good: Path, tmp_path: Path) -> None:
    import cv2

    root = copy(good, tmp_path)
    data = load_toml(root / "session.toml")
    for cam in ("cam1", "cam2", "cam3", "cam4"):
        frames = sorted((root / "trials" / "throw" / cam).glob("*.png"))
        path = root / "video" / f"{cam}.avi"
        path.parent.mkdir(exist_ok=True)
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 50, (752, 291), False)
        for f in frames:
            writer.write(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE))
        writer.release()
    cut = root / "video" / "cam2.avi"
    cut.write_bytes(cut.read_bytes()[: cut.stat().st_size // 3])
    data["trials"] = [{"name": "thrown", "video": "video/{camera}.avi"}]
    (root / "session.toml").write_text(tomli_w.dumps(data))
    result = kisscal("reconstruct", str(root), "thrown")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "cam2" in result.stderr or "video" in result.stderr


def test_unknown_parameter_in_config(good: Path, tmp_path: Path) -> None:
    root = copy(good, tmp_path)
    data = load_toml(root / "session.toml")
    data["detection"] = {"treshold": 50}
    (root / "session.toml").write_text(tomli_w.dumps(data))
    assert_one_line_error(kisscal("run", str(root)), "treshold", "did you mean 'threshold'")
