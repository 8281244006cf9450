"""Every stage's parameters for one session: defaults <- ``session.toml`` <- command line.

:func:`stage_params` is the one place where the values a user wrote (``session.toml``
tables, command-line overrides) are turned into the stages' typed, checked parameter
dataclasses. Everything downstream receives the :class:`StageParams` it returns (or one of
its members) and never reads a raw table again.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kisscal.bundle.params import BundleParams
from kisscal.detect import DetectionParams
from kisscal.dlt import DltParams
from kisscal.dlt.linear import spread_ratio
from kisscal.errors import EstimationFailed
from kisscal.gait import GaitParams
from kisscal.grid import GridParams
from kisscal.io.config import SessionConfig
from kisscal.params import Params
from kisscal.recon import ReconParams
from kisscal.report.params import ReportParams
from kisscal.target.params import TargetParams
from kisscal.tracking import TrackingParams


@dataclass(frozen=True)
class Overrides:
    """Parameter overrides from the command line, per stage (``{"pnc": 0.05}`` ...)."""

    detection: Mapping[str, Any] = field(default_factory=dict)
    grid: Mapping[str, Any] = field(default_factory=dict)
    dlt: Mapping[str, Any] = field(default_factory=dict)
    recon: Mapping[str, Any] = field(default_factory=dict)
    tracking: Mapping[str, Any] = field(default_factory=dict)
    gait: Mapping[str, Any] = field(default_factory=dict)
    wand: Mapping[str, Any] = field(default_factory=dict)
    target: Mapping[str, Any] = field(default_factory=dict)
    report: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class StageParams:
    """Every stage's parameters for one session, resolved once by :func:`stage_params`.

    ``detection`` holds the defaults with what the user gave; each camera's own settings
    are derived from its images (:func:`kisscal.session.runner.markers_detection`,
    :func:`~kisscal.session.runner.camera_detection`), keeping the values in
    ``detection_given`` (the same values, typed, by name: what the derivation must not
    change).
    """

    detection: DetectionParams
    grid: GridParams
    dlt: DltParams
    recon: ReconParams
    tracking: TrackingParams
    gait: GaitParams
    wand: BundleParams = field(default_factory=BundleParams)
    target: TargetParams = field(default_factory=TargetParams)
    report: ReportParams = field(default_factory=ReportParams)
    detection_given: Mapping[str, Any] = field(default_factory=dict)


#: Each member of :class:`StageParams` and its class (whose ``section`` names its table).
MEMBERS: dict[str, type[Params]] = {
    "detection": DetectionParams,
    "grid": GridParams,
    "dlt": DltParams,
    "recon": ReconParams,
    "tracking": TrackingParams,
    "gait": GaitParams,
    "wand": BundleParams,
    "target": TargetParams,
    "report": ReportParams,
}


def _layers(config: SessionConfig, name: str) -> dict[str, Any]:
    """The values ``session.toml`` gives for one member of :class:`StageParams`."""
    if name == "detection":
        return dict(config.detection)
    values: dict[str, Any] = {}
    if name == "grid" and config.grid is not None:
        values = {"rows": config.grid.rows, "cols": config.grid.cols}
    return {**values, **config.sections.get(MEMBERS[name].section, {})}


def stage_params(config: SessionConfig, overrides: Overrides | None = None) -> StageParams:
    """Parameters of every stage from ``session.toml`` sections and CLI overrides.

    Every value is converted and checked here, once (a bad one is a one-line error naming
    its table); the control points ``[rods]`` gives are checked against the resolved
    ``[dlt]`` limits (``min_points``, ``min_spread_ratio``).
    """
    o = overrides or Overrides()
    built = {
        name: cls.from_layers(_layers(config, name), getattr(o, name))
        for name, cls in MEMBERS.items()
    }
    named = {**config.detection, **o.detection}
    given = {k: getattr(built["detection"], k) for k in named}
    params = StageParams(**built, detection_given=given)
    if config.rods is not None:
        points = np.concatenate([rod.points_mm for rod in config.rods.rods])
        check_control_points_mm(config, "rods.rod", points, params.dlt)
    return params


def check_control_points_mm(
    config: SessionConfig, where: str, pts: np.ndarray, dlt: DltParams
) -> None:
    """Control points given in ``session.toml`` must determine a DLT under ``[dlt]``:
    ``min_points`` or more, not (nearly) coplanar (``min_spread_ratio``)."""
    if len(pts) < dlt.min_points:
        raise EstimationFailed(
            f"{config.path}: {where} gives {len(pts)} points; the DLT needs at least "
            f"{dlt.min_points} ([dlt] min_points)"
        )
    if not spread_ratio(pts) >= dlt.min_spread_ratio:
        raise EstimationFailed(
            f"{config.path}: {where} points are coplanar; the DLT needs points off one plane "
            f"(spread ratio {spread_ratio(pts):.1e} < [dlt] min_spread_ratio "
            f"{dlt.min_spread_ratio:g})"
        )
