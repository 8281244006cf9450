"""Gait events and spatiotemporal parameters from labelled marker trajectories.

``detect_events`` finds foot strikes and foot offs (:mod:`kisscal.gait.events`),
``spatiotemporal_parameters`` the clinical parameters (:mod:`kisscal.gait.spatiotemporal`),
``gait_cycle_figure`` draws them (:mod:`kisscal.gait.figures`). The heavier modules load
on first use, so that importing the event table (as the synthetic walker does) stays
cheap.

Example
-------
>>> from kisscal.gait import GaitParams
>>> GaitParams().hysteresis
0.3
"""

from importlib import import_module
from typing import Any

from kisscal.gait.markers import GaitMarkers, gait_markers, heel_from_ankle
from kisscal.gait.params import GaitParams
from kisscal.gait.table import GaitEvents

_LAZY = {
    "detect_events": "kisscal.gait.events",
    "progression": "kisscal.gait.events",
    "spatiotemporal_parameters": "kisscal.gait.spatiotemporal",
    "Spatiotemporal": "kisscal.gait.spatiotemporal",
    "UNITS": "kisscal.gait.spatiotemporal",
    "gait_cycle_figure": "kisscal.gait.figures",
}

__all__ = ["GaitEvents", "GaitMarkers", "GaitParams", "gait_markers", "heel_from_ankle", *_LAZY]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'kisscal.gait' has no attribute {name!r}")
