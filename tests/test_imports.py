"""What ``kisscal run`` imports before it works: no plotting.

matplotlib (about 1 s) is imported by the figure process and the report when they draw,
never by the process that runs the stages.
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
