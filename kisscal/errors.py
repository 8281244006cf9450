"""User-facing errors, one class per thing a caller can do about them.

Anything a user can cause raises a :class:`KisscalError`; the CLI prints its message on
one line and exits with code 2. Its subclasses tell a caller which of three things went
wrong, so that a script can act on it without reading the message:

- :class:`InputError`: a value, a shape or a setting is wrong (fix the call or
  ``session.toml``);
- :class:`MissingDataError`: a file or an earlier stage's output is not there (run the
  stage first, or point at the file);
- :class:`EstimationFailed`: the input was well formed but a fit did not succeed (too
  few points, a degenerate configuration, no convergence): more or better data is needed.
  Like scikit-image's ``FailedEstimation`` (van der Walt et al. 2014), it is an outcome
  of the data, not a bug.

The base class itself is raised only where several kinds meet (a summary of failures) or
none of them fits (a locked session); :func:`with_context` adds context to an error and
keeps its kind. Programming errors keep their tracebacks.

References
----------
van der Walt, S., Schönberger, J. L., Nunez-Iglesias, J., Boulogne, F., Warner, J. D.,
Yager, N., Gouillart, E., & Yu, T. (2014). scikit-image: image processing in Python.
PeerJ, 2, e453.
"""

from __future__ import annotations


class KisscalError(ValueError):
    """An error caused by the user's input, reported on one line without a traceback.

    A :class:`ValueError`, so that library callers catching bad values catch it too.
    """

    exit_code: int = 2


class InputError(KisscalError):
    """A value, an array shape or a setting the caller gave is not acceptable."""


class MissingDataError(KisscalError, FileNotFoundError):
    """A file, or the output of an earlier stage, is not there.

    Also a :class:`FileNotFoundError`, so that code catching a missing file catches it.
    """


class EstimationFailed(KisscalError):
    """A fit on well-formed input did not succeed: too few or degenerate data."""


def with_context(error: KisscalError, prefix: str = "", suffix: str = "") -> KisscalError:
    """``error`` told again with ``prefix`` before and ``suffix`` after its message, of
    the same kind, so that adding context (the camera, the file) does not hide what a
    caller can do about it: ``raise with_context(exc, f"camera {cam}: ") from None``."""
    return type(error)(f"{prefix}{error}{suffix}")
