"""User-facing errors.

Anything a user can cause (a missing folder, a bad number, a degenerate calibration)
raises :class:`KisscalError`; the CLI prints its message on one line and exits with
code 2. Programming errors keep their tracebacks.
"""

from __future__ import annotations


class KisscalError(ValueError):
    """An error caused by the user's input, reported on one line without a traceback.

    A :class:`ValueError`, so that library callers catching bad values catch it too.
    """

    exit_code: int = 2
