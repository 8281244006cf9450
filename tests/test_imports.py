"""What the CLI imports before it works: no plotting for ``kisscal run``, no NumPy for
``kisscal --help``.

matplotlib (about 1 s) is imported by the figure process and the report when they draw,
never by the process that runs the stages; kisscal.session (NumPy, SciPy, OpenCV: some
3 s on a loaded machine) when a command runs, not when the CLI parses its arguments.
"""

from __future__ import annotations

import subprocess
import sys


def test_the_run_command_imports_no_plotting() -> None:
    code = (
        "import sys, kisscal.cli.app, kisscal.session.run, kisscal.gait.events; "
        "print(sorted(m for m in sys.modules if m.startswith('matplotlib')))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"


def test_the_cli_starts_without_numpy_or_the_session() -> None:
    """``kisscal --help`` (and an option mistyped) loads the commands only: kisscal.session,
    with NumPy, SciPy and OpenCV, is imported when a command runs (cli.app.session_package,
    and the detect command's table reader and writer)."""
    code = (
        "import sys, kisscal.cli.commands; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('numpy', 'scipy', 'cv2') "
        "or m.startswith('kisscal.session')))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"
