"""What ``kisscal run`` imports before it works: nothing heavy that only some paths use.

matplotlib is imported by the figure process and the report when they draw; scipy.signal
(and with it scipy.stats, about 1 s) not at all: the gait helpers are written on numpy.
"""

from __future__ import annotations

import subprocess
import sys

HEAVY = ("matplotlib", "scipy.stats", "scipy.signal")


def test_the_run_command_imports_no_plotting_and_no_scipy_stats() -> None:
    code = (
        "import sys, kisscal.cli.app, kisscal.session.run, kisscal.gait.events; "
        f"print(sorted(m for m in sys.modules if m.startswith({HEAVY!r})))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]"
