"""The seeds' validation trials, measured from trajectories: the stick and the thrown marker.

Shafiq et al. 2001 (section 5.1) validate 3D reconstruction by moving a stick with two
markers 502.5 mm apart through the volume (mean absolute length error 1.1 mm, SD 1.5 mm
over 200 samples) and by throwing a marker: parabolas fitted to X, Y and Z over time give
the accelerations, the vertical one compared with g (under 1 % error).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.report.markers import MEASURED, Dense, segment_lengths

_STICK_NAME = re.compile(r"stick", re.IGNORECASE)
_THROW_NAME = re.compile(r"throw|ball|projectile|drop", re.IGNORECASE)
#: A pair of trajectories is taken for a stick when its length varies less than this
#: (relative SD): rigid-body noise, far below what two independent markers show.
STICK_MAX_CV = 0.01
#: Unnamed trials with more trajectories than this are not validation trials.
VALIDATION_MAX_TRACKS = 4


@dataclass(frozen=True)
class StickLength:
    """Length of the validation stick over a trial (mm), where both markers are measured."""

    a: str
    b: str
    time_s: NDArray[np.float64]
    length_mm: NDArray[np.float64]
    true_mm: float

    @property
    def valid(self) -> NDArray[np.float64]:
        return self.length_mm[np.isfinite(self.length_mm)]

    @property
    def mean_mm(self) -> float:
        return float(self.valid.mean())

    @property
    def sd_mm(self) -> float:
        return float(self.valid.std())

    @property
    def mean_abs_error_mm(self) -> float:
        return float(np.abs(self.valid - self.true_mm).mean())

    @property
    def samples(self) -> int:
        return len(self.valid)


@dataclass(frozen=True)
class ThrowFit:
    """Parabolas fitted to a thrown marker's X, Y and Z over time.

    Attributes
    ----------
    label : str
        The trajectory.
    time_s : ndarray, shape (n,)
        Times of the measured samples.
    xyz_mm : ndarray, shape (n, 3)
        The measured samples.
    coefficients : ndarray, shape (3, 3)
        Per axis, ``numpy.polyfit`` coefficients (t², t, 1) in mm and seconds.
    """

    label: str
    time_s: NDArray[np.float64]
    xyz_mm: NDArray[np.float64]
    coefficients: NDArray[np.float64]

    @property
    def acceleration_m_s2(self) -> NDArray[np.float64]:
        """Acceleration along X, Y, Z (m/s²): twice the t² coefficients."""
        return 2.0 * self.coefficients[:, 0] / 1000.0

    @property
    def g_m_s2(self) -> float:
        """Downward acceleration (m/s²), lab Z up."""
        return float(-self.acceleration_m_s2[2])

    def fitted_mm(self) -> NDArray[np.float64]:
        return np.stack([np.polyval(c, self.time_s) for c in self.coefficients], axis=1)

    @property
    def rms_mm(self) -> float:
        """RMS distance of the samples to the fitted path (mm)."""
        return float(np.sqrt(np.mean(np.sum((self.xyz_mm - self.fitted_mm()) ** 2, axis=1))))


def _by_measured(dense: Dense) -> NDArray[np.int64]:
    """Trajectory indices, most measured samples first."""
    return np.argsort(-(dense.status == MEASURED).sum(axis=1), kind="stable")


def stick_length(
    dense: Dense, trial: str, rate_hz: float, true_mm: float = 502.5, named_only: bool = False
) -> StickLength | None:
    """The stick's length over a trial, or None when the trial is not a stick trial.

    The stick's markers are the two longest trajectories. A trial named like a stick
    (``stick`` in its name) is always measured; another trial with at most
    :data:`VALIDATION_MAX_TRACKS` trajectories is when the two keep their distance within
    :data:`STICK_MAX_CV` (a gait trial's pelvis markers would too, hence the count limit),
    unless ``named_only`` (a trial labelled with the session's marker set, say).

    References
    ----------
    Shafiq, Tümer, Güler 2001, section 5.1.

    Examples
    --------
    >>> from kisscal.report.markers import dense_trajectories
    >>> t = np.arange(50)
    >>> a = np.column_stack([t, 0 * t, 0 * t]); b = a + [0, 502.5, 0]
    >>> d = dense_trajectories(np.r_[t, t], np.r_[0 * t, 0 * t + 1], ["M1"] * 50 + ["M2"] * 50,
    ...                        np.r_[a, b], ["measured"] * 100)
    >>> s = stick_length(d, "t1", 50.0)
    >>> round(s.mean_mm, 3), s.samples
    (502.5, 50)
    """
    if len(dense.labels) < 2:
        return None
    named = bool(_STICK_NAME.search(trial))
    if not named and (named_only or len(dense.labels) > VALIDATION_MAX_TRACKS):
        return None
    i, j = sorted(_by_measured(dense)[:2])
    a, b = dense.labels[i], dense.labels[j]
    length = segment_lengths(dense, a, b)
    ok = length[np.isfinite(length)]
    if len(ok) < 2:
        return None
    if not named and not (ok.std() < STICK_MAX_CV * ok.mean() and len(ok) >= 10):
        return None
    return StickLength(a, b, np.arange(dense.n_fields) / rate_hz, length, float(true_mm))


def throw_fit(
    dense: Dense, trial: str, rate_hz: float, g_m_s2: float = 9.81, named_only: bool = False
) -> ThrowFit | None:
    """Parabolas fitted to a thrown marker, or None when the trial is not a throw.

    The thrown marker is the longest trajectory. A trial named like a throw (``throw``,
    ``ball``, ``projectile``, ``drop``) is always fitted; another trial with at most
    :data:`VALIDATION_MAX_TRACKS` trajectories is when its fit gives a downward
    acceleration within 30 % of ``g_m_s2`` and follows the samples within 5 mm RMS,
    unless ``named_only``.

    References
    ----------
    Shafiq, Tümer, Güler 2001, section 5.1.

    Examples
    --------
    >>> from kisscal.report.markers import dense_trajectories
    >>> t = np.arange(40) / 50.0
    >>> xyz = np.column_stack([1000 * t, 0 * t, 1500 + 3000 * t - 4905 * t**2])
    >>> d = dense_trajectories(np.arange(40), np.zeros(40), ["M1"] * 40, xyz, ["measured"] * 40)
    >>> round(throw_fit(d, "t2", 50.0).g_m_s2, 3)
    9.81
    """
    if not dense.labels:
        return None
    named = bool(_THROW_NAME.search(trial))
    if not named and (named_only or len(dense.labels) > VALIDATION_MAX_TRACKS):
        return None
    k = int(_by_measured(dense)[0])
    fields = np.flatnonzero(dense.status[k] == MEASURED)
    if len(fields) < 5:
        return None
    t = fields / rate_hz
    xyz = dense.xyz_mm[k, fields]
    coefficients = np.stack([np.polyfit(t, xyz[:, d], 2) for d in range(3)])
    fit = ThrowFit(dense.labels[k], t, xyz, coefficients)
    if not named and not (abs(fit.g_m_s2 - g_m_s2) < 0.3 * g_m_s2 and fit.rms_mm < 5.0):
        return None
    return fit


def rate_doubt(fit: ThrowFit, rate_hz: float, g_m_s2: float = 9.81, max_error: float = 0.02) -> str:
    """Why ``rate_hz`` may be wrong, from a thrown marker that does not fall at ``g_m_s2``
    (``""`` when it does, within ``max_error``, or rises).

    Positions per field are what the cameras measured; time is fields / rate, so the
    fitted acceleration scales with the square of the rate: ``rate_hz * sqrt(g / fitted)``
    is the rate at which the marker would fall at ``g_m_s2``.

    Examples
    --------
    >>> t = np.arange(40) / 50.0  # thrown at 50 Hz, processed as if at 30 Hz
    >>> xyz = np.column_stack([1000 * t, 0 * t, 1500 + 3000 * t - 4905 * t**2])
    >>> fit = ThrowFit("M1", np.arange(40) / 30.0, xyz, np.stack(
    ...     [np.polyfit(np.arange(40) / 30.0, xyz[:, d], 2) for d in range(3)]))
    >>> doubt = rate_doubt(fit, 30.0)
    >>> doubt.split(":")[0], doubt.split("? ")[1]
    ('a thrown marker falls at 3.53 m/s² (-64 % of 9.81)', 'it would fall at 9.81 m/s² at 50 Hz')
    """
    g = fit.g_m_s2
    if g <= 0 or abs(g - g_m_s2) <= max_error * g_m_s2:
        return ""
    rate = rate_hz * float(np.sqrt(g_m_s2 / g))
    return (
        f"a thrown marker falls at {g:.2f} m/s² ({100 * (g - g_m_s2) / g_m_s2:+.0f} % of "
        f"{g_m_s2:g}): is [session] rate_hz = {rate_hz:g} right? it would fall at "
        f"{g_m_s2:g} m/s² at {rate:.3g} Hz"
    )
