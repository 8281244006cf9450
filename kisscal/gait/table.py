"""The gait event table: ``side,event,field,time_s`` (events.csv, the C3D EVENT group)."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

SIDES = ("left", "right")
EVENTS = ("foot_strike", "foot_off")
#: Vicon's names for the C3D EVENT group (LABELS, CONTEXTS).
C3D_LABELS = {"foot_strike": "Foot Strike", "foot_off": "Foot Off"}
C3D_CONTEXTS = {"left": "Left", "right": "Right"}


@dataclass(frozen=True, eq=False)
class GaitEvents:
    """Foot strikes and foot offs of one trial, sorted by time.

    Attributes
    ----------
    side : ndarray of str, shape (n,)
        ``"left"`` or ``"right"``.
    event : ndarray of str, shape (n,)
        ``"foot_strike"`` or ``"foot_off"``.
    time_s : ndarray, shape (n,)
        Time of the event in seconds from the first field (field 0 at 0 s); detected
        events carry sub-field precision.
    rate_hz : float
        Field rate; ``field`` is ``time_s * rate_hz`` rounded to the nearest field.
    warnings : tuple of str
        Why events or full strides are missing (one line each; empty when none are).
    """

    side: NDArray[np.str_]
    event: NDArray[np.str_]
    time_s: NDArray[np.float64]
    rate_hz: float
    warnings: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        order = np.argsort(self.time_s, kind="stable")
        for name in ("side", "event", "time_s"):
            value = np.asarray(getattr(self, name))[order]
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @classmethod
    def from_times(
        cls,
        times: Mapping[tuple[str, str], Iterable[float]],
        rate_hz: float,
        warnings: Iterable[str] = (),
    ) -> GaitEvents:
        """Build from ``{(side, event): times_s}``."""
        sides, events, t = [], [], []
        for (side, event), values in times.items():
            if side not in SIDES or event not in EVENTS:
                raise ValueError(f"unknown side/event {(side, event)!r}")
            values = [float(v) for v in values]
            sides += [side] * len(values)
            events += [event] * len(values)
            t += values
        return cls(
            np.array(sides, dtype="<U5"),
            np.array(events, dtype="<U11"),
            np.array(t, dtype=float),
            float(rate_hz),
            tuple(warnings),
        )

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def field(self) -> NDArray[np.int64]:
        """Nearest field index of each event."""
        return np.rint(self.time_s * self.rate_hz).astype(np.int64)

    def times(self, side: str, event: str) -> NDArray[np.float64]:
        """Sorted times (s) of one side's events of one kind."""
        return self.time_s[(self.side == side) & (self.event == event)]

    def rows(self) -> list[dict[str, object]]:
        """The ``events.csv`` rows: ``side, event, field, time_s``."""
        return [
            {"side": str(s), "event": str(e), "field": int(f), "time_s": float(t)}
            for s, e, f, t in zip(self.side, self.event, self.field, self.time_s, strict=True)
        ]

    def c3d(self) -> dict[str, object]:
        """The C3D EVENT group's values (Vicon layout): LABELS, CONTEXTS, TIMES.

        ``TIMES`` is (2, n): row 0 whole minutes, row 1 seconds, as the C3D standard
        stores event times.
        """
        minutes = np.floor(self.time_s / 60.0)
        return {
            "LABELS": [C3D_LABELS[str(e)] for e in self.event],
            "CONTEXTS": [C3D_CONTEXTS[str(s)] for s in self.side],
            "TIMES": np.stack([minutes, self.time_s - 60.0 * minutes]),
        }
