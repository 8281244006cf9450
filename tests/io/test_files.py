"""io.files.staged_folder: a session folder appears whole or not at all."""

from __future__ import annotations

from pathlib import Path

import pytest

from kisscal.errors import InputError, KisscalError, MissingDataError
from kisscal.io.files import read_text, staged_folder


def test_a_failed_block_leaves_nothing_and_keeps_what_was_there(tmp_path: Path) -> None:
    out = tmp_path / "session"
    out.mkdir()
    (out / "old.txt").write_text("kept")
    with pytest.raises(RuntimeError), staged_folder(out, force=True) as root:
        (root / "new.txt").write_text("half")
        raise RuntimeError("render failed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["session"]
    assert sorted(p.name for p in out.iterdir()) == ["old.txt"]


def test_a_finished_block_replaces_the_folder(tmp_path: Path) -> None:
    out = tmp_path / "session"
    out.mkdir()
    (out / "old.txt").write_text("gone")
    with staged_folder(out, force=True) as root:
        (root / "new.txt").write_text("whole")
    assert sorted(p.name for p in out.iterdir()) == ["new.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["session"]


def test_a_full_folder_needs_force_and_a_file_is_refused(tmp_path: Path) -> None:
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "a").write_text("x")
    with pytest.raises(KisscalError, match="not empty"), staged_folder(tmp_path / "full"):
        pass
    (tmp_path / "file").write_text("x")
    with pytest.raises(KisscalError, match="not a folder"), staged_folder(tmp_path / "file"):
        pass


def test_read_text_drops_a_byte_order_mark_and_tells_missing_from_unreadable(
    tmp_path: Path,
) -> None:
    path = tmp_path / "t.csv"
    path.write_bytes(b"\xef\xbb\xbfa,b\r\n1,2\r\n")
    assert read_text(path) == "a,b\n1,2\n"
    with pytest.raises(MissingDataError, match=r"nope\.csv: points file not found"):
        read_text(tmp_path / "nope.csv", "points file")
    path.write_bytes(b"a,\xff\n")
    with pytest.raises(InputError, match="not UTF-8 text"):
        read_text(path)
