"""The documentation builds with warnings as errors and lists every command there is."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_docs_build_strict(tmp_path: Path) -> None:
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-d", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert (tmp_path / "site" / "your-lab" / "index.html").is_file()


def test_commands_page_lists_every_command() -> None:
    from kisscal.cli import app

    commands = {c.name or c.callback.__name__ for c in app.registered_commands if c.callback}
    page = (ROOT / "docs" / "commands.md").read_text()
    documented = set(re.findall(r"^\| `kisscal (\w+)", page, flags=re.M))
    assert documented == commands


def test_readme_names_only_what_exists() -> None:
    readme = (ROOT / "README.md").read_text()
    for path in re.findall(r"\]\(([^)#:]+)\)", readme):  # relative links
        assert (ROOT / path).exists(), path
