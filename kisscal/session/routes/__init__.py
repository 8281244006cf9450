"""Calibration routes of ``kisscal calibrate``: one module per way a lab calibrates.

Each route takes a :class:`RouteInputs` and writes ``out/dlt/<camera>.json`` for the cameras
it calibrates (plus its own extra files); :func:`kisscal.session.calibrate.calibrate` picks
the route from the session, writes what every route shares (``dltdv.csv``,
``calibration.json``) and hands the result on. Everything downstream reads only those files.

Routes: :mod:`~kisscal.session.routes.rods` (surveyed rods, the seeds' method) and
:mod:`~kisscal.session.routes.points` (control points given per camera).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from kisscal.grid import Linearisation
from kisscal.io.config import CameraConfig, SessionConfig
from kisscal.session.params import StageParams
from kisscal.session.progress import Echo


@dataclass(frozen=True)
class RouteInputs:
    """What every calibration route is given.

    Attributes
    ----------
    root : Path
        The session folder.
    config : SessionConfig
    cameras : tuple of CameraConfig
        The cameras to calibrate (all, or the one given with ``--camera``).
    linearisations : dict
        Each camera's current grid linearisation (identity without a grid).
    params : StageParams
    echo : Echo
        Where log lines go.
    workers : int or None
        Detection processes.
    """

    root: Path
    config: SessionConfig
    cameras: tuple[CameraConfig, ...]
    linearisations: dict[str, Linearisation]
    params: StageParams
    echo: Echo
    workers: int | None = None

    @property
    def whole_rig(self) -> bool:
        """True when every camera of the session is calibrated (rig-wide checks apply)."""
        return len(self.cameras) == len(self.config.cameras)
