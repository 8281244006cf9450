"""What the wand route writes: the version-1 files, ``dlt/wand.json``, checks and figures.

Each camera's lens terms are folded into the 30-coefficient linearisation polynomial
(fitted over the whole image to the grid's linearisation followed by the lens inverse,
or to the lens inverse alone without a grid) and its DLT is the distortion-free camera
``K [R | t]``, so every later stage reads the same files as after the rods route.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from kisscal.bundle.adjust import WandPoses, centred_offsets
from kisscal.bundle.params import BundleParams
from kisscal.bundle.points import trial_markers_weight
from kisscal.bundle.quality import (
    camera_figures,
    end_to_end_mm,
    field_lengths,
    held_out_fields,
    held_out_lengths,
    leave_one_group_out,
    length_figures,
    paired_length_gain,
    triangulate_points,
    wand_markers,
)
from kisscal.bundle.wand import AxesFrame, WandCalibration
from kisscal.camera import LENS_TERMS, Camera
from kisscal.dlt import make_rods
from kisscal.dlt.rig import RodCalibration
from kisscal.io.dltfiles import write_dlt_outputs
from kisscal.io.files import write_json
from kisscal.report.dlt import rig_figure
from kisscal.report.wand import WandView, coverage_figure, length_figure
from kisscal.session.inputs import figure
from kisscal.session.linearise import restore_grid_linearisations
from kisscal.session.routes import RouteInputs, write_check
from kisscal.session.routes.lens_files import write_lens_camera
from kisscal.session.routes.wand_judge import (
    Judgement,
    PairedErrors,
    held_out_markers,
    length_evidence,
    markers_burden,
)

ROUTE = "wand"


def wand_params(inputs: RouteInputs) -> BundleParams:
    """The adjustment's parameters: on the rods with a grid, see ``grid_lens``."""
    config, params = inputs.config, inputs.params.wand
    return (
        params.on_grid()
        if config.grid is not None and config.rods is not None
        else params.off_grid()
    )


def write_wand_outputs(
    inputs: RouteInputs,
    cal: WandCalibration,
    frame: AxesFrame | None,
    rod_cal: RodCalibration | None,
    seconds: float,
    baseline: WandCalibration | None = None,
    weighing: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Write every output of the wand route; returns the ``check.json`` content.

    ``rod_cal`` is the calibration the wand's must not be worse than (the rods alone, or
    the rods and trials adjusted together: ``baseline``, their adjustment); ``weighing``
    the rods' weights fitted and the one kept (``wand.json`` entries)."""
    config = inputs.config
    markers = cal.markers(config.wand.markers_mm)  # with the trials' markers' own
    ids = config.camera_ids
    sizes = [c.size_px for c in config.cameras]
    cameras = frame.cameras(cal.written) if frame is not None else cal.written
    inlier = cal.observations.subset(cal.result.inlier)
    lengths = end_to_end_mm(
        wand_markers(cal.written, inlier, len(cal.fields), len(markers)), markers
    )
    held = held_out_lengths(cal, markers, wand_params(inputs))
    nominal = float(np.ptp(markers))
    per_cam = camera_figures(cal, sizes)
    wand_doc: dict[str, Any] = {
        "trial": config.wand.trial,
        "markers_mm": list(config.wand.markers_mm),
        "start": "rods" if rod_cal is not None else "axes",
        **length_figures(lengths, nominal),
        "held_out": length_figures(held, nominal),
        "fields_used": int(np.sum(cal.fields >= 0)),
        "iterations": cal.result.iterations,
        "seconds": round(seconds, 2),
        "cameras": {
            cam: _camera_entry(cameras[c], cal.cameras[c], per_cam, c) for c, cam in enumerate(ids)
        },
    }
    if cal.control is not None:
        wand_doc["rods_weight"] = float(cal.control.weight)
        wand_doc.update(weighing or {})
    if np.any(cal.fields < 0):
        wand_doc["trial_markers_used"] = int(np.sum(cal.fields < 0))
        wand_doc["trial_markers_weight"] = trial_markers_weight(cal)
    if rod_cal is not None:
        fields = held_out_fields(len(cal.fields), wand_params(inputs))
        # the rods' cameras on the grid's linearisation (Kolahi's terms when chosen)
        res = rod_cal.results
        rods = [Camera.from_dlt(res[c].L, c, None, res[c].lens) for c in ids]
        alone = field_lengths(rods, cal, fields, markers)
        wand_doc["held_out_rods_alone"] = {
            **length_figures(alone, nominal),
            "wand_minus_rods": paired_length_gain(held, alone, nominal),
        }
    check, markers = _checks(inputs, cal, rod_cal, wand_doc, baseline)
    if markers is not None:
        wand_doc["held_out_rod_markers"] = check["held_out_rod_markers"] = markers.as_dict()
    if frame is not None:
        wand_doc["axes"] = _axes_entry(frame, ids)
    params = wand_params(inputs)
    burden = 0.0
    if rod_cal is not None:
        terms = params.resect_terms if cal.resected is not None else 0
        burden = markers_burden(rod_cal, terms, params.keep_sigmas)
    judgement = Judgement(
        markers or PairedErrors(0), length_evidence(wand_doc), params.keep_sigmas, burden
    )
    check["judges"] = judgement.as_dict()
    wand_doc["kept"] = check["kept"] = judgement.kept if rod_cal is not None else "wand"
    if check["kept"] == "rods":
        check["leave_out_mean_mm"] = check["leave_one_rod_out"]["rods_alone_mean_mm"]
        _keep_rods(inputs, rod_cal)
    else:
        _write_cameras(inputs, cal, cameras, frame)
    write_check(inputs, check)
    write_json(inputs.store.calibration_file("wand"), wand_doc)
    _say(inputs, wand_doc, check)
    _figures(inputs, cal, cameras, per_cam, lengths)
    return check


def _keep_rods(inputs: RouteInputs, rod_cal: RodCalibration) -> None:
    """Write the rods' calibration, on the grid's own linearisation (none without a
    grid), as the result: a lens an earlier run's wand estimated does not stay behind."""
    store = inputs.store
    write_dlt_outputs(rod_cal, store.dlt_path, store.dltdv_path)
    restore_grid_linearisations(store.root, [cam.id for cam in inputs.cameras], "rods")


def _camera_entry(cam: Camera, adjusted: Camera, per_cam: Any, c: int) -> dict[str, Any]:
    """One camera's figures: the written camera's pinhole, the adjustment's Brown terms
    and, when resected, the written Kolahi terms."""
    entry = {
        "rms_px": float(per_cam.rms_px[c]),
        "points": int(per_cam.points[c]),
        "coverage": float(per_cam.coverage[c]),
        "fu_px": float(cam.K[0, 0]),
        "fv_px": float(cam.K[1, 1]),
        "u0_px": float(cam.K[0, 2]),
        "v0_px": float(cam.K[1, 2]),
        "skew_px": float(cam.K[0, 1]),
    }
    entry.update({term: float(v) for term, v in zip(LENS_TERMS, adjusted.lens, strict=True)})
    if cam.kolahi is not None:
        entry["kolahi_L12_L16"] = [float(v) for v in cam.kolahi]
    return entry


def _axes_entry(frame: AxesFrame, ids: Sequence[str]) -> dict[str, Any]:
    m = frame.match
    seen = frame.seen.sum(axis=1)
    n = frame.seen.shape[1]
    return {
        "rms_mm": m.rms_mm,
        "scale": m.scale,
        "markers_seen": {cam: int(seen[c]) for c, cam in enumerate(ids)},
        "markers": n,
    }


def _checks(
    inputs: RouteInputs,
    cal: WandCalibration,
    rod_cal: RodCalibration | None,
    wand_doc: dict[str, Any],
    baseline: WandCalibration | None = None,
) -> tuple[dict[str, Any], PairedErrors | None]:
    """``check.json``: the held-out 3D figures ``kisscal check --max-3d-mm`` reads; and the
    held-out rod markers of both calibrations (None without the rods)."""
    check: dict[str, Any] = {"route": ROUTE, "wand_held_out": wand_doc["held_out"]}
    if "held_out_rods_alone" in wand_doc:
        check["wand_held_out_rods_alone"] = wand_doc["held_out_rods_alone"]
    held = wand_doc["held_out"]
    if "length_rms_error_mm" in held:
        check["leave_out_mean_mm"] = held["length_rms_error_mm"]
    if rod_cal is None or cal.control is None:
        return check, None
    markers = cal.markers(inputs.config.wand.markers_mm)
    control = cal.control
    ids_xyz, point = np.unique(control.xyz_mm, axis=0, return_inverse=True)
    xyz = triangulate_points(
        cal.written, control.camera, point.ravel(), control.uv_px, len(ids_xyz)
    )
    err = np.linalg.norm(xyz - ids_xyz, axis=1)
    check["rods_in_sample_mean_mm"] = float(np.nanmean(err))
    check["rods_in_sample_max_mm"] = float(np.nanmax(err))
    loo = leave_one_group_out(cal, markers, wand_params(inputs))
    names = [r.name for r in inputs.config.rods.rods] if inputs.config.rods else []
    rods_alone = rod_cal.summary().get("leave_one_rod_out", {}).get("per_rod", {})
    per_rod = {}
    for g, e in loo.items():
        name = names[g]
        per_rod[name] = {
            "mean_mm": float(np.mean(e)),
            "max_mm": float(np.max(e)),
            "n_markers": len(e),
            "rods_alone_mean_mm": rods_alone.get(name, {}).get("mean_mm"),
        }
    every = np.concatenate(list(loo.values())) if loo else np.zeros(0)
    check["leave_one_rod_out"] = {
        "mean_mm": float(np.mean(every)),
        "max_mm": float(np.max(every)),
        "per_rod": per_rod,
        "rods_alone_mean_mm": rod_cal.summary().get("leave_one_rod_out", {}).get("mean_mm"),
    }
    check["leave_out_mean_mm"] = check["leave_one_rod_out"]["mean_mm"]
    rods = make_rods([(r.name, r.points_mm) for r in inputs.config.rods.rods])
    held = held_out_markers(
        cal,
        rod_cal,
        rods,
        inputs.config.camera_ids,
        markers,
        inputs.params.dlt,
        wand_params(inputs),
        baseline,
    )
    check["compared_with"] = _compared_with(rod_cal, baseline)
    return check, held


def _compared_with(rod_cal: RodCalibration, baseline: WandCalibration | None) -> str:
    """What the wand's calibration was judged against (kept, as ``rods``, when the wand's
    is not): the rods alone, or the rods and trials adjusted together (by which trials)."""
    if baseline is None:
        return "rods alone"
    models = rod_cal.models
    return models.by if models is not None else "rods and trials adjusted together"


def _write_cameras(
    inputs: RouteInputs, cal: WandCalibration, cameras: Sequence[Camera], frame: AxesFrame | None
) -> None:
    """``linearisation/<camera>.json`` (lens folded in) and ``dlt/<camera>.json``."""
    config = inputs.config
    r, obs = cal.result, cal.observations
    wand = r.wand
    if frame is not None:
        Q, shift = frame.match.rotation, frame.match.shift_mm
        wand = WandPoses(wand.centre_mm @ Q.T + shift, wand.direction @ Q.T)
    offsets = centred_offsets(cal.markers(config.wand.markers_mm))
    xyz_obs = wand.centre_mm[obs.field] + offsets[obs.marker, None] * wand.direction[obs.field]
    names = [rod.name for rod in config.rods.rods] if config.rods else []
    for c, cfg in enumerate(config.cameras):
        rows = (obs.camera == c) & r.inlier
        fields, marks = cal.fields[obs.field[rows]], obs.marker[rows]
        # a trial's marker adjusted with the wand (trial field -1) by its row
        labels = [
            f"W{m + 1}@{f}" if f >= 0 else f"T@{k}"
            for k, (f, m) in enumerate(zip(fields, marks, strict=True))
        ]
        kinds = np.where(fields >= 0, "wand", "trial").tolist()
        xyz, uv, res = xyz_obs[rows], obs.uv_px[rows], r.residuals_px[rows]
        if cal.control is not None:
            ctl = cal.control.camera == c
            xyz = np.concatenate([cal.control.xyz_mm[ctl], xyz])
            uv = np.concatenate([cal.control.uv_px[ctl], uv])
            res = np.concatenate([r.control_residuals_px[ctl], res])
            labels = [f"{names[g]}@{i}" for i, g in enumerate(cal.control.group[ctl])] + labels
            kinds = ["rod"] * int(ctl.sum()) + kinds
        extra = {"wand": {"trial": config.wand.trial}}
        write_lens_camera(
            inputs, cfg, cameras[c], ROUTE, (xyz, uv, res, labels), r.iterations, extra, kinds=kinds
        )


def _say(inputs: RouteInputs, wand_doc: dict[str, Any], check: dict[str, Any]) -> None:
    echo = inputs.echo
    other = check.get("compared_with", "rods alone")
    for cam, e in wand_doc["cameras"].items():
        echo(
            f"  calibrate {cam}: wand, {e['points']} wand points, rms {e['rms_px']:.3f} px, "
            f"image covered {e['coverage']:.0%}"
        )
    if "length_mean_mm" in wand_doc:
        w = wand_doc
        echo(
            f"  wand length {w['length_mean_mm']:.3f} mm, SD {w['length_sd_mm']:.3f} mm, "
            f"RMS error {w['length_rms_error_mm']:.3f} mm over {w['length_fields']} fields"
            f" ({w['seconds']:.1f} s)"
        )
    held = wand_doc["held_out"]
    alone = wand_doc.get("held_out_rods_alone", {}).get("length_rms_error_mm")
    if "length_rms_error_mm" in held:
        echo(
            f"  held-out wand fields: length RMS error {held['length_rms_error_mm']:.3f} mm"
            + (f" ({other} {alone:.3f} mm)" if alone is not None else "")
        )
    loo = check.get("leave_one_rod_out")
    if loo:
        alone = loo.get("rods_alone_mean_mm")
        echo(
            f"  leave-one-rod-out mean {loo['mean_mm']:.3f} mm"
            + (f" ({other} {alone:.3f} mm)" if alone is not None else "")
        )
    markers = check.get("held_out_rod_markers", {})
    if "wand_rms_mm" in markers:
        echo(
            f"  held-out rod markers ({markers['markers']}, each left out of both "
            f"calibrations): RMS 3D error {markers['wand_rms_mm']:.3f} mm "
            f"({other} {markers['rods_alone_rms_mm']:.3f} mm)"
        )
    if check.get("kept") == "rods":
        failed = [
            f"{k} ({v['asks']})" for k, v in check.get("judges", {}).items() if not v["wand_passes"]
        ] or ["held-out rod markers not measured"]
        echo(
            f"  the wand's calibration is not kept, held out it is not better than the "
            f"{other} ({', '.join(failed)}): kept that calibration (the wand's figures "
            "stay in dlt/wand.json)"
        )
    elif check.get("judges"):
        echo(f"  the wand's calibration is kept: held out, not worse than the {other}")
    axes = wand_doc.get("axes")
    if axes:
        n = axes["markers"]
        for cam, k in axes["markers_seen"].items():
            if k < n:
                echo(f"  warning: axes: {cam} sees {k} of the {n} axes markers")


def _figures(
    inputs: RouteInputs,
    cal: WandCalibration,
    cameras: Sequence[Camera],
    per_cam: Any,
    lengths: np.ndarray,
) -> None:
    config = inputs.config
    obs = cal.observations.subset(cal.result.inlier)
    views = {
        cfg.id: WandView(
            obs.uv_px[obs.camera == c],
            cfg.size_px,
            float(per_cam.coverage[c]),
            float(per_cam.rms_px[c]),
        )
        for c, cfg in enumerate(config.cameras)
    }
    root = inputs.root
    figure(root, "wand_coverage", coverage_figure, views)
    nominal = float(np.ptp(config.wand.markers_mm)) if config.wand else 0.0
    wand = cal.fields >= 0  # not the trials' markers adjusted with it
    figure(root, "wand_length", length_figure, cal.fields[wand], lengths[wand], nominal)
    objects = [(r.name, r.points_mm) for r in config.rods.rods] if config.rods else []
    if config.axes is not None:
        objects.append(("axes", config.axes.points_mm))
    figure(
        root,
        "rig",
        rig_figure,
        {cfg.id: cameras[c].centre_mm for c, cfg in enumerate(config.cameras)},
        objects,
        {cfg.id: cameras[c].R for c, cfg in enumerate(config.cameras)},
    )
