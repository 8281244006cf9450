"""io.files.staged_folder: a session folder appears whole or not at all."""

from __future__ import annotations

from pathlib import Path

import pytest

from kisscal.errors import KisscalError
from kisscal.io.files import staged_folder


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
