"""``kisscal calibrate``: each camera's DLT, by the route the session describes.

The routes live in :mod:`kisscal.session.routes`, one module each; this module picks one,
keeps the calibration switches a user chose (``--mdlt``, ``--refine``, ``--lens``) across
later runs, writes what every route shares (``out/dlt/calibration.json`` and the exports:
``out/dlt/dltdv.csv``, ``out/cameras.toml``) and leaves the calibrated
:class:`~kisscal.rig.Rig` for :func:`kisscal.session.calibrated.current_rig` to read.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path
from typing import Any

from kisscal.dlt.params import DltParams
from kisscal.errors import InputError
from kisscal.io.config import SessionConfig
from kisscal.io.files import write_json
from kisscal.io.store import SessionStore
from kisscal.session.ahead import Ahead
from kisscal.session.calibrated import read_dlt_files
from kisscal.session.exports import write_exports
from kisscal.session.inputs import select_cameras, writes_session
from kisscal.session.linearise import (
    current_linearisations,
    grid_linearisations,
    restore_grid_linearisations,
)
from kisscal.session.params import Overrides, stage_params
from kisscal.session.progress import Echo, quiet
from kisscal.session.routes import RouteInputs
from kisscal.session.routes.imported import calibrate_from_cameras, calibrate_from_dltdv
from kisscal.session.routes.points import calibrate_from_points
from kisscal.session.routes.rods import calibrate_from_rods
from kisscal.session.routes.target import calibrate_from_target
from kisscal.session.routes.trial_bundle import has_files, usable_trials, uses_trials
from kisscal.session.routes.wand import calibrate_from_wand

#: Every route by name: what ``calibration.json`` records and ``--route`` chooses.
ROUTES: dict[str, Callable[[RouteInputs], dict[str, Any]]] = {
    "rods": calibrate_from_rods,
    "points": calibrate_from_points,
    "cameras": calibrate_from_cameras,
    "dlt": calibrate_from_dltdv,
    "wand": calibrate_from_wand,
    "target": calibrate_from_target,
}


@writes_session
def calibrate(
    root: Path,
    camera: str | None = None,
    mdlt: bool | None = None,
    refine: bool | None = None,
    lens: bool | None = None,
    overrides: Overrides | None = None,
    echo: Echo = quiet,
    workers: int | None = None,
    route: str | None = None,
    refresh: bool = False,
    *,
    config: SessionConfig,
    ahead: Ahead | None = None,
) -> dict[str, Any]:
    """``kisscal calibrate``: DLT parameters of each camera, by the session's route.

    ``route`` forces one of :data:`ROUTES` (``--route``); by default the session's
    tables choose it (:func:`session_route`), and the choice is said.

    ``mdlt``, ``refine`` and ``lens`` left as ``None`` keep what the last calibration of
    this session chose (``out/dlt/calibration.json``), so that ``kisscal run`` never
    silently undoes ``kisscal calibrate --mdlt``; ``False`` turns a switch off.

    The trials the rods are adjusted with (``[dlt] trials_bundle``) are recorded there
    too and reused, as a lab expects of a calibration: made once, it stays as it was
    when a walk is added later, until ``refresh`` (``--refresh``) makes it again with
    every trial the session has then (:func:`_bundle_trials`). ``[dlt] bundle_trials``
    named in ``session.toml`` decides instead. ``ahead``: the trials' blobs ``kisscal
    run`` detects in the background (:class:`~kisscal.session.ahead.Ahead`).

    Writes ``out/dlt/<camera>.json``, ``out/dlt/calibration.json`` and the exports
    (``out/dlt/dltdv.csv``, ``out/cameras.toml``, ``out/exports.json``);
    returns ``{camera: DltResult}`` plus the route's held-out check under ``"_check"``.
    ``config`` is the session's, read from ``root`` when the caller has none
    (:func:`~kisscal.session.inputs.loads_config`).
    """
    root = Path(root)
    o = overrides or Overrides()
    switches = _dlt_switches(root, {"mdlt": mdlt, "refine": refine, "lens": lens}, echo)
    params = stage_params(config, dataclasses.replace(o, dlt={**o.dlt, **switches}))
    route, why = session_route(config, route)
    previous = SessionStore(root).calibration_doc("calibration") or {}
    # the wand route adjusts the same trials with the wand (and judges against them)
    if route in ("rods", "wand") and params.dlt.trials_bundle and params.dlt.selects:
        trials = _bundle_trials(config, params.dlt, previous, refresh, echo)
        dlt = dataclasses.replace(params.dlt, bundle_trials=trials)
        params = dataclasses.replace(params, dlt=dlt)
    echo(f"  calibrate: route {route} ({why})")
    cameras, lins = select_cameras(config, camera), grid_linearisations(config, echo)
    inputs = RouteInputs(root, config, cameras, lins, params, echo, workers, ahead)
    summary = ROUTES[route](inputs)
    restore_grid_linearisations(root, [c.id for c in inputs.cameras], route)
    lins = current_linearisations(config, quiet)  # a wand's or target's lens, where estimated
    write_exports(root, config, lins, read_dlt_files(root, config, False), echo, workers)
    record = {"route": route, "options": switches, **_kept(summary.get("_check"))}
    # the trials the rods were adjusted with, or those of the calibration before (a
    # forced model or one camera leaves the record for the next default calibration)
    used = params.dlt.bundle_trials if route in ("rods", "wand") and uses_trials(inputs) else ()
    kept = used or previous.get("bundle_trials")
    write_json(
        SessionStore(root).calibration_file("calibration"),
        {**record, "bundle_trials": list(kept)} if kept else record,
    )
    return summary


def _kept(check: dict[str, Any] | None) -> dict[str, Any]:
    """The wand route's choice, for ``calibration.json``: which calibration was kept,
    against which, and each held-out judge's verdict on the wand's (empty otherwise)."""
    if not check or "kept" not in check or "judges" not in check:
        return {}
    verdicts = {k: v["wand_passes"] for k, v in check["judges"].items()}
    why = {"compared_with": check.get("compared_with"), "wand_passes": verdicts}
    return {"kept": check["kept"], "kept_why": why}


def _bundle_trials(
    config: SessionConfig,
    dlt: DltParams,
    previous: dict[str, Any],
    refresh: bool,
    echo: Echo,
) -> tuple[str, ...]:
    """The trials the rods are adjusted with: ``[dlt] bundle_trials`` when named; else
    those the session's calibration recorded (``previous``, ``calibration.json``) that it
    still has, so that a walk added later leaves the calibration as it was; else, and with
    ``refresh``, every image or video trial it has now (the wand's aside).

    Named explicitly either way, so that the calibration's cache key is the same whether
    the trials came from the record or from the session.
    """
    if dlt.bundle_trials:
        return dlt.bundle_trials
    usable = tuple(usable_trials(config))
    recorded = [] if refresh else previous.get("bundle_trials") or []
    kept = tuple(n for n in recorded if n in usable)
    if not kept:  # a trial without its files is left to fail on its own
        return tuple(n for n, t in usable_trials(config).items() if has_files(config, t))
    if set(usable) - set(kept):
        echo(
            f"  calibrate: the rods stay adjusted with {', '.join(kept)}, as this session "
            f"was calibrated (--refresh adds {', '.join(sorted(set(usable) - set(kept)))})"
        )
    return kept


def session_route(config: SessionConfig, forced: str | None = None) -> tuple[str, str]:
    """The calibration route a session describes (a key of :data:`ROUTES`) and why.

    ``[wand]`` calibrates on the rods when there are rods, else with the axes object;
    without a wand, ``[rods]``, else ``[calibration]``. ``forced`` (``--route``) must be
    a route the session has the inputs for.
    """
    available = _available_routes(config)
    if config.wand is not None and config.rods is None and config.axes is None:
        raise InputError(
            f"{config.path}: [wand] needs [rods] or [axes] to fix the lab frame and origin"
        )
    if forced is not None:
        if forced not in ROUTES:
            raise InputError(f"--route {forced}: unknown route; choose one of {', '.join(ROUTES)}")
        if forced not in available:
            raise InputError(
                f"--route {forced}: {config.path} has no inputs for it "
                f"({_NEEDS.get(forced, 'see docs/session-format.md')})"
            )
        return forced, "--route"
    if config.calibration is not None and config.calibration.route not in ROUTES:
        raise InputError(
            f"{config.path}: [calibration] {config.calibration.route} is not supported by "
            "this version of kisscal"
        )
    if not available:
        raise InputError(
            f"{config.path}: no [rods], [wand] or [calibration]: nothing to calibrate from"
        )
    route, why = next(iter(available.items()))
    return route, why


_NEEDS = {
    "rods": "[rods]",
    "cameras": "[calibration] cameras",
    "dlt": "[calibration] dlt",
    "wand": "[wand] with [rods] or [axes]",
    "points": "[calibration] points",
    "target": "[calibration] target, images and seeds",
}


def _available_routes(config: SessionConfig) -> dict[str, str]:
    """Routes the session has inputs for, the default first, each with its reason."""
    out = {}
    if config.wand is not None and (config.rods is not None or config.axes is not None):
        on = "on the rods" if config.rods is not None else "with the axes object"
        out["wand"] = f"[wand] {on}"
    if config.rods is not None:
        out["rods"] = "[rods]"
    if config.calibration is not None and config.calibration.route in ROUTES:
        out[config.calibration.route] = f"[calibration] {config.calibration.route}"
    return out


_SWITCHES = ("mdlt", "refine", "lens")


def _dlt_switches(root: Path, given: dict[str, bool | None], echo: Echo) -> dict[str, bool]:
    """The DLT switches: those given, else those the session's last calibration used."""
    previous = (SessionStore(root).calibration_doc("calibration") or {}).get("options", {})
    chosen = {k: v for k, v in given.items() if v is not None}
    kept = {k: True for k in _SWITCHES if previous.get(k) and k not in chosen}
    if kept:
        names = ", ".join(f"--{k}" for k in kept)
        echo(f"  calibrate: keeping {names} from this session's last calibration")
    return {**kept, **chosen}
