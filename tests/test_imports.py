"""What the CLI imports before it works: no plotting for ``kisscal run``, no NumPy for
``kisscal --help``.

matplotlib (about 1 s) is imported by the figure process and the report when they draw,
never by the process that runs the stages; kisscal.session (NumPy, SciPy, OpenCV: some
3 s on a loaded machine) when a command runs, not when the CLI parses its arguments.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

from kisscal.cli.blas import THREAD_VARIABLES, one_thread


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


def _threads_when_numpy_loads(environ: dict[str, str]) -> dict[str, str | None]:
    """The thread variables as NumPy's import finds them, under ``python -m kisscal``'s
    imports (:mod:`kisscal.__main__`), in a fresh interpreter with ``environ``."""
    code = (
        "import json, os, sys\n"
        f"names = {list(THREAD_VARIABLES)!r}\n"  # kisscal.cli.blas itself not imported
        "seen = {}\n"
        "class Watch:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'numpy' and not seen:\n"
        "            seen.update({v: os.environ.get(v) for v in names})\n"
        "sys.meta_path.insert(0, Watch())\n"
        "import kisscal.__main__, kisscal.session.run\n"
        "print(json.dumps(seen))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, env=environ
    )
    return json.loads(done.stdout)


def _without_thread_variables() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if k not in THREAD_VARIABLES}


def test_the_cli_gives_the_blas_libraries_one_thread_before_numpy_loads() -> None:
    """NumPy, SciPy and OpenCV read their thread counts when they load: the command
    line sets them first (issue 28: BLAS threads in every worker process oversubscribed
    two cores)."""
    seen = _threads_when_numpy_loads(_without_thread_variables())
    assert seen == dict.fromkeys(THREAD_VARIABLES, "1")


def test_a_users_thread_setting_is_kept() -> None:
    """OpenBLAS falls back to ``OMP_NUM_THREADS``: a user's ``OMP_NUM_THREADS=2`` alone
    must not be overridden by an ``OPENBLAS_NUM_THREADS`` of kisscal's."""
    seen = _threads_when_numpy_loads({**_without_thread_variables(), "OMP_NUM_THREADS": "2"})
    assert seen == {"OPENBLAS_NUM_THREADS": None, "MKL_NUM_THREADS": None, "OMP_NUM_THREADS": "2"}


def test_one_thread_sets_every_variable_or_none() -> None:
    fresh: dict[str, str] = {"PATH": "/bin"}
    one_thread(fresh)
    assert fresh == {"PATH": "/bin", **dict.fromkeys(THREAD_VARIABLES, "1")}
    chosen = {"MKL_NUM_THREADS": "4"}
    one_thread(chosen)
    assert chosen == {"MKL_NUM_THREADS": "4"}
