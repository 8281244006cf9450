"""Gait events and spatiotemporal parameters from labelled marker trajectories.

Example
-------
>>> from kisscal.gait import GaitParams
>>> GaitParams().hysteresis
0.3
"""

from kisscal.gait.events import detect_events, progression
from kisscal.gait.figures import gait_cycle_figure
from kisscal.gait.markers import GaitMarkers, gait_markers
from kisscal.gait.params import GaitParams
from kisscal.gait.spatiotemporal import UNITS, Spatiotemporal, spatiotemporal
from kisscal.gait.table import GaitEvents

__all__ = [
    "UNITS",
    "GaitEvents",
    "GaitMarkers",
    "GaitParams",
    "Spatiotemporal",
    "detect_events",
    "gait_cycle_figure",
    "gait_markers",
    "progression",
    "spatiotemporal",
]
