"""Report sections of the calibration: cameras, rods, detection settings, wand."""

from __future__ import annotations

import math
from typing import Any

from kisscal.report.gather import SessionOutputs
from kisscal.report.htmlkit import (
    Html,
    badge,
    details,
    esc,
    fmt,
    heading,
    join,
    png,
    section,
    table,
    tag,
)
from kisscal.report.status import Verdict

RMS_NOTE = (
    "Residuals are RMS Euclidean distances in pixels, sqrt(mean(du² + dv²)); tools that "
    "report a per-coordinate RMS give about 1/√2 of it."
)


def _centre(c: tuple[float, float, float] | None) -> list[str]:
    return ["–"] * 3 if c is None else [fmt(v, 0) for v in c]


def camera_table(o: SessionOutputs, verdicts: dict[str, Verdict]) -> Html:
    """One row per camera: grid before/after, dots, DLT method, rms, points, centre."""
    figures = {c: o.camera_figures(c) for c in o.cameras}
    headers = [
        "camera",
        "status",
        "grid residual before (px)",
        "after (px)",
        "dots used",
        "DLT method",
        "control points",
        "DLT rms (px)",
        "centre X (mm)",
        "Y (mm)",
        "Z (mm)",
    ]
    exported = any(f.exported for f in figures.values())
    if exported:
        headers.append("cameras.toml fit rms (px)")
    headers.append("missing rod markers")
    rows = []
    for cam in o.cameras:
        f = figures[cam]
        dlt = o.dlt.get(cam)
        missing = dlt.missing_rod_markers if dlt is not None else ()
        row = [
            tag("b", cam),
            badge(verdicts[cam].state) if cam in verdicts else "",
            fmt(f.grid_rms_px_before) if f.grid else "no grid",
            fmt(f.grid_rms_px) if f.grid else "–",
            fmt(f.dots_used),
            f.dlt_method or "–",
            fmt(dlt.n_points if dlt is not None else None),
            fmt(f.dlt_rms_px),
            *_centre(f.centre_mm),
        ]
        if exported:
            row.append(fmt(f.export_fit_rms_px, 4))
        row.append(", ".join(missing) if missing else "none")
        rows.append(row)
    return table(headers, rows, numeric=(2, 3, 4, 6, 7, 8, 9, 10, 11))


def rod_table(o: SessionOutputs) -> Html:
    """Held-out 3D error per rod (leave-one-rod-out) and the in-sample error."""
    check = o.rig_check()
    parts = []
    if math.isfinite(check.in_sample_mean_mm):
        parts.append(
            tag(
                "p",
                f"Rod markers reconstructed with every rod in the fit: mean "
                f"{fmt(check.in_sample_mean_mm, 3)} mm, max "
                f"{fmt(check.in_sample_max_mm, 3)} mm. Each rod held out of the "
                "fit and reconstructed by the others (the honest figure):",
            )
        )
    if check.per_rod:
        alone = any(math.isfinite(r.rods_alone_mean_mm) for r in check.per_rod)
        rows = [
            [tag("b", r.name), fmt(r.n_markers), fmt(r.mean_mm), fmt(r.max_mm)]
            + ([fmt(r.rods_alone_mean_mm)] if alone else [])
            for r in check.per_rod
        ]
        headers = ["rod held out", "markers", "3D error mean (mm)", "max (mm)"]
        if alone:  # the wand route: the same rod held out of the rods-only calibration
            headers.append("rods alone, mean (mm)")
        parts.append(table(headers, rows, tuple(range(1, len(headers)))))
    return join(parts)


def model_table(o: SessionOutputs) -> Html:
    """The camera models compared on held-out points (``lens_models`` of each camera's
    ``dlt/<camera>.json``): one row per camera, the chosen model marked."""
    docs = {c: m for c in o.cameras if (m := o.lens_models(c)) is not None}
    if not docs:
        return Html("")
    first = next(iter(docs.values()))
    models = list(first.models)
    rows = []
    for cam, doc in docs.items():
        cells = []
        for m in models:
            text = fmt(doc.held_out_rms_px(m), 4)
            cells.append(tag("b", text) if m == doc.chosen else text)
        rows.append([tag("b", cam), doc.chosen, *cells])
    rig_3d = (fmt(first.models[m].held_out_3d_rms_mm, 4) for m in models)
    rows.append(["rig, 3D (mm)", first.chosen, *rig_3d])
    names = [f"{m}: {first.models[m].model}, held-out (px)" for m in models]
    note = tag(
        "p",
        f"Camera model chosen by {esc(first.by)}: each model fitted with one of "
        f"{first.folds} subsets of the control points left out in turn (with rods: each "
        "rod, then one marker of every rod; otherwise interleaved points), and judged on "
        "the points it did not see. The rows give each camera's held-out reprojection "
        "error, the last row the RMS 3D error of the held-out points reconstructed by the "
        "rig (with rods, the geometric mean of the two ways of leaving points out). "
        "--mdlt, --refine or --lens overrides.",
    )
    return join([note, table(["camera", "chosen", *names], rows, tuple(range(2, 2 + len(models))))])


def target_table(o: SessionOutputs) -> Html:
    """Target points matched per camera (``[calibration] target``) and the held-out error."""
    record = o.target()
    if record is None:
        return Html("")
    figures = ("visible", "matched", "unmatched", "rms_px", "written_rms_px", "seed_rms_px")
    rows = [
        [tag("b", c), *(fmt(getattr(e, f)) for f in figures)] for c, e in record.cameras.items()
    ]
    headers = ["camera", "visible points", "matched", "unmatched", "matching rms (px)"]
    headers += ["written rms (px)", "seeds rms (px)"]
    parts = [table(headers, rows, (1, 2, 3, 4, 5, 6))]
    check = o.rig_check()
    if math.isfinite(check.leave_out_mean_mm):
        held = check.held_out_points if check.held_out_points is not None else ""
        parts.append(
            tag(
                "p",
                f"{held} target points held out of every camera's fit "
                f"and reconstructed from all cameras: mean {fmt(check.leave_out_mean_mm, 3)}"
                f" mm, max {fmt(check.leave_out_max_mm, 3)} mm.",
            )
        )
    return join(parts)


def calibration_section(o: SessionOutputs, verdicts: dict[str, Verdict], used: set[str]) -> Html:
    """Cameras table, rods, and the calibration figures (grid figures folded)."""
    parts: list[Any] = [camera_table(o, verdicts), model_table(o), rod_table(o), target_table(o)]
    fig = o.figures
    if "rig" in fig:
        used.add("rig")
        parts.append(
            png(
                fig["rig"],
                "cameras and rods",
                "Cameras (squares, with optical axes) and the "
                "surveyed calibration rods in the lab frame (mm).",
                width="620px",
            )
        )
    if "dlt_residuals" in fig:
        used.add("dlt_residuals")
        parts.append(
            png(
                fig["dlt_residuals"],
                "DLT residuals",
                "DLT reprojection residual of each rod "
                "marker, drawn in the image (arrows magnified; the key arrow gives the scale).",
            )
        )
    targets = []
    for cam in o.cameras:
        name = f"target_{cam}"
        if name in fig:
            used.add(name)
            targets.append(details(f"{cam}: matched target points", png(fig[name], name)))
    if targets:
        parts.append(tag("h3", "Target residuals per camera (click to open)"))
        parts.append(join(targets))
    grids = []
    for cam in o.cameras:
        name = f"grid_{cam}"
        if name in fig:
            used.add(name)
            g = o.camera_figures(cam)
            line = f"{cam}: grid residual {fmt(g.grid_rms_px_before)} → {fmt(g.grid_rms_px)} px"
            grids.append(details(line, png(fig[name], f"grid {cam}")))
    if grids:
        parts.append(tag("h3", "Grid linearisation per camera (click to open)"))
        parts.append(join(grids))
    return section("calibration", "Calibration", join(parts), RMS_NOTE)


#: Detection settings shown in the report, in order, with their column headings.
DETECTION_COLUMNS = (
    ("threshold", "threshold"),
    ("background_tile_px", "local background tile (px)"),
    ("pixel_aspect", "pixel aspect"),
    ("max_pixels", "oversize above (px)"),
    ("detach_kernel_px", "detach kernel (px)"),
)


def detection_section(o: SessionOutputs) -> Html:
    """The detection settings derived per camera (``out/detection/<camera>.json``)."""
    rows = []
    for cam, record in o.detection.items():
        for kind, entry in record.kinds.items():
            given = [k for k, s in entry.settings.items() if s.source == "given"]
            values = entry.values()
            low, high = entry.marker_pixels
            rows.append(
                [
                    tag("b", cam),
                    esc(kind),
                    *(fmt(values.get(k, "–")) for k, _ in DETECTION_COLUMNS),
                    f"{low}–{high}" if high else "–",
                    fmt(entry.noise_sigma),
                    esc(", ".join(given) or "–"),
                ]
            )
    if not rows:
        return Html("")
    headers = ["camera", "images", *(h for _, h in DETECTION_COLUMNS), "markers (px)"]
    return section(
        "detection",
        "Detection settings per camera",
        table([*headers, "noise (grey levels)", "given"], rows),
        "Values given in [detection] are used as given; the others were derived from each "
        "camera's own images (reasons in out/detection/<camera>.json).",
    )


WAND_NOTE = (
    "Wand length: every field's end markers triangulated afresh from the calibrated "
    "cameras; held out: fields left out of the adjustment. Coverage: the share of an 8 x 8 "
    "division of the image the wand reached (lens terms are extrapolated elsewhere). "
)


def wand_section(o: SessionOutputs, used: set[str]) -> Html:
    """Wand calibration figures (``out/dlt/wand.json``): length, per-camera residuals."""
    w = o.wand
    if w is None:
        return Html("")
    parts = []
    if w.kept == "rods":
        why = (
            ": the rods' calibration is kept (rod markers held out in turn and the held-out "
            "wand fields, rods alone against wand); the wand's figures are below."
        )
        parts.append(tag("p", join([tag("b", "The wand did not lower the held-out error"), why])))
    if w.rods_weighed:
        how = "by their own noise" if w.rods_weighed == "own_noise" else "as the rods route does"
        said = f"Rods weighed {how}: the lower leave-one-rod-out error of the two fits below."
        parts.append(tag("p", esc(said)))
    if w.figures:
        rows = [[heading(k), fmt(v)] for k, v in w.figures]
        parts.append(table(["wand figure", "value"], rows, (1,)))
    if w.cameras:
        keys = w.camera_columns
        rows = [[tag("b", c), *(fmt(d.get(k, "–")) for k in keys)] for c, d in w.cameras.items()]
        headers = ["camera", *(heading(k) for k in keys)]
        parts.append(table(headers, rows, tuple(range(1, len(keys) + 1))))
    for name in sorted(o.figures):
        if name.startswith("wand"):
            used.add(name)
            parts.append(png(o.figures[name], name, name.replace("_", " ")))
    return section("wand", "Wand calibration", join(parts), esc(WAND_NOTE + RMS_NOTE))
