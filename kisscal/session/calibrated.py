"""The calibrated rig of a processed session, for the stages after calibration.

``kisscal calibrate`` writes each camera's DLT (``out/dlt/<camera>.json``) and, where a
route estimated a lens, its linearisation; :func:`current_rig` reads them back with the
grid linearisations (brought up to date first) as one :class:`~kisscal.rig.Rig`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from kisscal.camera import Camera
from kisscal.errors import MissingDataError
from kisscal.grid import Linearisation
from kisscal.io.config import SessionConfig
from kisscal.io.dltfiles import DltFile
from kisscal.io.store import SessionStore
from kisscal.rig import Rig
from kisscal.session.inputs import loads_config
from kisscal.session.linearise import current_linearisations
from kisscal.session.progress import Echo, quiet


def read_dlt_files(root: Path, config: SessionConfig, required: bool = True) -> dict[str, DltFile]:
    """Every camera's calibration from ``out/dlt/<camera>.json`` (L1..L11, lens terms ...)."""
    result = {}
    store = SessionStore(root)
    for cam in config.camera_ids:
        path = store.dlt_path(cam)
        if path.is_file():
            result[cam] = store.dlt(cam)
        elif required:
            raise MissingDataError(f"{path}: missing; run `kisscal calibrate {root}` first")
    return result


@loads_config
def current_rig(root: Path, echo: Echo = quiet, *, config: SessionConfig) -> Rig:
    """The session's calibrated rig: current linearisations and the written DLT files.

    Linearises the cameras whose grid linearisation is missing or out of date (writing
    ``out/linearisation/``); raises :class:`~kisscal.errors.MissingDataError` when a
    camera has no calibration yet (``kisscal calibrate`` first). ``config`` is the
    session's, read from ``root`` when the caller has none.
    """
    lins = current_linearisations(config, echo)
    return calibrated_rig(config, lins, read_dlt_files(root, config))


def calibrated_rig(
    config: SessionConfig, lins: Mapping[str, Linearisation], dlts: Mapping[str, DltFile]
) -> Rig:
    """The cameras of the session that have a DLT, in session order."""
    return Rig(
        tuple(
            Camera.from_dlt(dlts[c.id].L, c.id, lins.get(c.id), dlts[c.id].lens, c.size_px)
            for c in config.cameras
            if c.id in dlts
        )
    )
