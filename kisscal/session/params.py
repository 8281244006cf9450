"""Every stage's parameters for one session: defaults <- ``session.toml`` <- command line."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from kisscal.bundle.params import BundleParams
from kisscal.detect import DetectionParams
from kisscal.dlt import DltParams
from kisscal.errors import InputError
from kisscal.gait import GaitParams
from kisscal.grid import GridParams
from kisscal.io.config import SessionConfig
from kisscal.params import Params
from kisscal.recon import ReconParams
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


@dataclass(frozen=True)
class StageParams:
    """Every stage's parameters for one session.

    ``detection`` holds the defaults with what the user gave; each camera's own settings
    are derived from its images (:func:`kisscal.session.configure.camera_detection`),
    starting from ``detection_given``.
    """

    detection: DetectionParams
    grid: GridParams
    dlt: DltParams
    recon: ReconParams
    tracking: TrackingParams
    gait: GaitParams
    wand: BundleParams = field(default_factory=BundleParams)
    target: TargetParams = field(default_factory=TargetParams)
    detection_given: Mapping[str, Any] = field(default_factory=dict)


def build_params(cls: type, section: str, *layers: Mapping[str, Any]) -> Any:
    """A stage's parameter dataclass from config/CLI layers; unknown keys are errors."""
    if issubclass(cls, Params):
        return cls.from_layers(*layers)
    return _legacy_params(cls, section, *layers)


def _legacy_params(cls: type, section: str, *layers: Mapping[str, Any]) -> Any:
    """Parameter classes not yet on the :class:`~kisscal.params.Params` base."""
    import dataclasses
    import difflib

    names = [f.name for f in dataclasses.fields(cls)]
    values: dict[str, Any] = {}
    for layer in layers:
        for key, value in layer.items():
            if key not in names:
                close = difflib.get_close_matches(key, names, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise InputError(f"[{section}] unknown parameter {key!r}{hint}")
            values[key] = tuple(value) if isinstance(value, list) else value
    try:
        return cls(**values)
    except (TypeError, ValueError) as exc:
        raise InputError(f"[{section}] {exc}") from None


def stage_params(config: SessionConfig, overrides: Overrides | None = None) -> StageParams:
    """Parameters of every stage from ``session.toml`` sections and CLI overrides."""
    o = overrides or Overrides()
    grid_cfg: dict[str, Any] = {}
    if config.grid is not None:
        grid_cfg = {"rows": config.grid.rows, "cols": config.grid.cols}
        grid_cfg.update(config.sections.get("grid", {}))
    section = config.sections.get
    return StageParams(
        detection=build_params(DetectionParams, "detection", config.detection, o.detection),
        grid=build_params(GridParams, "grid", grid_cfg, o.grid),
        dlt=build_params(DltParams, "dlt", section("dlt", {}), o.dlt),
        recon=build_params(ReconParams, "recon", section("recon", {}), o.recon),
        tracking=build_params(TrackingParams, "tracking", section("tracking", {}), o.tracking),
        gait=build_params(GaitParams, "gait", section("gait", {}), o.gait),
        wand=build_params(BundleParams, "wand", section("wand", {}), o.wand),
        target=build_params(TargetParams, "target", section("target", {}), o.target),
        detection_given={**config.detection, **o.detection},
    )
