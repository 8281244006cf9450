"""`kisscal detect IMAGES... --out blobs.csv --overlay DIR` on synthetic frames."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from tests.io.blob_csv import read_blobs


def kisscal(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "kisscal", *args], capture_output=True, text=True, timeout=300
    )


def test_detect_writes_table_and_overlays(small_session: Path, tmp_path: Path) -> None:
    images = [small_session / "rods" / c / "000000.png" for c in ("cam1", "cam2")]
    images.append(small_session / "grid" / "cam1" / "000000.png")
    out = tmp_path / "blobs.csv"
    result = kisscal(
        "detect", *map(str, images), "--out", str(out), "--overlay", str(tmp_path / "ov")
    )
    assert result.returncode == 0, result.stderr
    table = read_blobs(out)
    assert set(table) == {str(p) for p in images}
    assert int(table[str(images[0])].valid.sum()) == 24  # the rods' markers
    assert int((~table[str(images[0])].valid).sum()) >= 1  # LED rings flagged invalid
    assert int(table[str(images[2])].valid.sum()) == 300  # the grid's dots
    assert len(list((tmp_path / "ov").glob("*.png"))) == 3  # same file names, no overwrite


@pytest.mark.parametrize("content", [b"", b"not an image at all"])
def test_detect_bad_file(tmp_path: Path, content: bytes) -> None:
    bad = tmp_path / "frame.png"
    bad.write_bytes(content)
    result = kisscal("detect", str(bad), "--out", str(tmp_path / "b.csv"))
    assert result.returncode == 2
    assert "frame.png" in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "b.csv").exists()
