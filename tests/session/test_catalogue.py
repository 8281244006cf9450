"""Every case of the bad-input catalogue: exit code, one clear line, earlier outputs kept."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.session.catalogue import CASES, Case, markdown

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def good(processed: Path) -> Path:
    """A processed four-camera session (walk01, stick, throw), 20 fields (conftest.py)."""
    return processed


def outputs(root: Path) -> dict[str, str]:
    """Hashes of the result files under out/ (not caches, keys, logs or the report)."""
    out = root / "out"
    kept = {}
    for path in sorted(out.rglob("*")) if out.is_dir() else ():
        if path.is_file() and path.suffix in (".json", ".csv", ".c3d", ".trc"):
            if path.name not in ("summary.json",) and "cache" not in path.parts:
                kept[str(path.relative_to(out))] = hashlib.sha256(path.read_bytes()).hexdigest()
    return kept


def kisscal(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "kisscal", *args], capture_output=True, text=True, timeout=600
    )


@pytest.mark.slow
@pytest.mark.parametrize("case", CASES, ids=[c.id for c in CASES])
def test_case(case: Case, good: Path, tmp_path: Path) -> None:
    root = tmp_path / "s"
    shutil.copytree(good, root)
    case.setup(root)
    before = outputs(root)
    args = [str(root) + a[1:] if a == "S" or a.startswith("S/") else a for a in case.args]
    result = kisscal(*args) if case.fault is None else in_process(args, case.fault)
    assert result.returncode == case.exit_code, result.stdout + result.stderr
    assert "Traceback" not in result.stderr + result.stdout
    if case.exit_code == 2:  # the log (stderr) may say what was done; one line says why not
        errors = [line for line in result.stderr.splitlines() if ": error: " in line]
        assert len(errors) == 1, result.stderr
        assert errors[0] == result.stderr.strip().splitlines()[-1], result.stderr
        assert errors[0].startswith(f"kisscal {case.args[0]}: error: "), errors[0]
        for word in case.says:
            assert word in errors[0], errors[0]
    for word in case.log:
        assert word in result.stderr, result.stderr
    assert not result.stdout.strip(), result.stdout  # the log is never on stdout
    if case.exit_code != 0:
        after = outputs(root)
        changed = [name for name, digest in before.items() if after.get(name) != digest]
        assert not changed, changed
        assert not list((root / "out").rglob("*.part*")) if (root / "out").is_dir() else True


def in_process(args: list[str], fault: str) -> subprocess.CompletedProcess[str]:
    """Run the CLI in this process with an OS error injected where files are written."""
    import contextlib
    import errno
    import io
    from unittest import mock

    from kisscal import cli

    def read_only(path: object, *a: object, **k: object) -> int:
        raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))

    def full(src: object, dst: object) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(dst))

    patch = (
        mock.patch("kisscal.io.lock.os.open", read_only)
        if fault == "erofs"
        else mock.patch("kisscal.io.files.os.replace", full)
    )
    out, err = io.StringIO(), io.StringIO()
    code = 0
    with patch, contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            cli.main(args)
        except SystemExit as exc:
            code = int(exc.code or 0)
    return subprocess.CompletedProcess(args, code, out.getvalue(), err.getvalue())


def test_catalogue_is_large_and_documented() -> None:
    assert len(CASES) >= 30 and len({c.id for c in CASES}) == len(CASES)
    assert (ROOT / "docs" / "bad-inputs.md").read_text() == markdown()
