"""Where ``cameras.toml``'s OpenCV cameras follow kisscal's: the volume the lab measures in
(the rods' markers and the trials' markers the wand was adjusted with, or ``[export]
volume_mm``), not the box a wand was waved through."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from kisscal.dlt import DltParams, calibrate_camera
from kisscal.io.config import parse_session
from kisscal.io.dltfiles import DltFile, read_dlt_json, write_dlt_json
from kisscal.opencv import opencv_from_camera
from kisscal.session.exports import _opencv_fits, fit_volume
from tests.test_opencv import bent_camera

SESSION = {
    "session": {"name": "lab", "rate_hz": 100},
    "cameras": [{"id": "c1", "size": [1280, 1024]}],
    "rods": {
        "images": "rods/{camera}/*.png",
        "rod": [{"name": "R1", "points_mm": [[0, 0, 0], [0, 0, 500]]}],
    },
}


def _points(labels: list[str], xyz: np.ndarray) -> list[dict]:
    return [
        {"label": lab, "x_mm": x, "y_mm": y, "z_mm": z}
        for lab, (x, y, z) in zip(labels, xyz.tolist(), strict=True)
    ]


def _lab(rng: np.random.Generator, ahead: np.ndarray, half: float, n: int) -> np.ndarray:
    return ahead + rng.uniform(-half, half, (n, 3))


def test_the_export_follows_kisscal_where_the_lab_measures_not_where_the_wand_went() -> None:
    """A lens no OpenCV model follows everywhere, calibrated by rods at the corners of a
    1.2 m box (``R1@<i>``), trial markers in it (``T@<row>``) and a wand waved through a
    box 2.5 times as wide (``W1@<field>``): OpenCV's camera images held-out points of the
    lab's box about as close to kisscal's as when fitted on that box itself, and closer
    than when fitted on every control point's hull (the export before: five times the
    gap on this rig)."""
    rng = np.random.default_rng(3)
    cam = bent_camera(rng)
    ahead = cam.R.T @ (np.array([0.0, 0.0, 4200.0]) - cam.t)  # on the optical axis
    half = 600.0
    corners = ahead + half * np.array(
        [[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    )
    rods = np.repeat(corners, 2, axis=0)
    trial = _lab(rng, ahead, half, 100)
    wand = _lab(rng, ahead, 2.5 * half, 600)
    labels = [f"R1@{i}" for i in range(len(rods))] + [f"T@{k}" for k in range(len(trial))]
    labels += [f"W1@{f}" for f in range(len(wand))]
    points = _points(labels, np.concatenate([rods, trial, wand]))
    dlts = {"c1": DltFile("c1", cam.dlt, "wand", data={"points": points})}
    config = parse_session(SESSION, Path("/lab"))

    volume = fit_volume(config, dlts)
    np.testing.assert_allclose(volume.box, (corners.min(axis=0), corners.max(axis=0)))
    assert len(volume.hull) == len(corners) + len(trial)
    assert volume.by == "control points but the wand's images" and volume.by_labels
    held_out = _lab(rng, ahead, half, 1000)

    def gap(fit) -> float:  # RMS px between the two cameras' images of the lab's points
        d = fit.camera.project(held_out) - cam.project(held_out)
        return float(np.sqrt(np.mean(np.sum(d**2, axis=1))))

    export = gap(_opencv_fits([cam], volume, dlts, workers=1)["c1"])
    box = (ahead - half, ahead + half)
    everywhere = np.concatenate([rods, trial, wand])
    wand_hull = (everywhere.min(axis=0), everywhere.max(axis=0))
    assert export < 1.1 * gap(opencv_from_camera(cam, volume_mm=box))
    assert export < 0.7 * gap(opencv_from_camera(cam, volume_mm=wand_hull, hull_mm=everywhere))


def test_export_volume_mm_replaces_the_control_points_and_a_wand_alone_is_kept() -> None:
    """``[export] volume_mm`` is the fit's box, whole (its corners in any order); a wand's
    images alone (no rods, no trial markers) still span the fit's volume; a rod named like
    a wand's marker keeps the points its label could name."""
    rng = np.random.default_rng(4)
    wand = rng.uniform(-1000, 1000, (50, 3))
    dlts = {
        "c1": DltFile(
            "c1",
            np.ones(11),
            "wand",
            data={"points": _points([f"W2@{f}" for f in range(50)], wand)},
        )
    }
    plain = {k: v for k, v in SESSION.items() if k != "rods"}
    volume = fit_volume(parse_session(plain, Path("/lab")), dlts)
    np.testing.assert_allclose(volume.box, (wand.min(axis=0), wand.max(axis=0)))
    assert len(volume.hull) == len(wand) and volume.by == "control points"
    rod = {
        **SESSION,
        "rods": {**SESSION["rods"], "rod": [{**SESSION["rods"]["rod"][0], "name": "W2"}]},
    }
    volume = fit_volume(parse_session(rod, Path("/lab")), dlts)
    assert len(volume.hull) == len(wand) and volume.by == "control points but the wand's images"
    assert volume.by_labels  # a file of an older kisscal: its labels tell, as they can
    given = {**plain, "export": {"volume_mm": [[10, 0, 2000], [-10, 50, 0]]}}
    volume = fit_volume(parse_session(given, Path("/lab")), dlts)
    assert volume.hull is None and volume.by == "export.volume_mm"
    np.testing.assert_allclose(volume.box, ([-10, 0, 0], [10, 50, 2000]))


def test_a_rod_named_like_a_wand_marker_leaves_the_wand_out_by_the_points_kind(
    tmp_path: Path,
) -> None:
    """A lab names its rod ``W1``: its markers (``W1@<i>``, kind ``rod``) and the wand's
    images of marker 1 (``W1@<field>``, kind ``wand``) share their labels. Written and
    read back, the file's kinds keep the export to the rods' and the trials' volume, as
    for a rod of any other name; the labels alone kept the wand's 600 images."""
    rng = np.random.default_rng(5)
    cam = bent_camera(rng)
    ahead = cam.R.T @ (np.array([0.0, 0.0, 4200.0]) - cam.t)
    corners = ahead + 600.0 * np.array(
        [[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    )
    trial, wand = _lab(rng, ahead, 600.0, 100), _lab(rng, ahead, 1500.0, 600)
    xyz = np.concatenate([corners, trial, wand])
    labels = [f"W1@{i}" for i in range(len(corners))] + [f"T@{k}" for k in range(len(trial))]
    labels += [f"W1@{f}" for f in range(len(wand))]
    kinds = ["rod"] * len(corners) + ["trial"] * len(trial) + ["wand"] * len(wand)
    result = calibrate_camera(xyz, cam.project_ideal(xyz), DltParams())
    path = write_dlt_json(tmp_path / "c1.json", "c1", result, xyz, None, labels, kinds=kinds)
    dlts = {"c1": read_dlt_json(path)}
    rod = {**SESSION["rods"]["rod"][0], "name": "W1", "points_mm": corners[:2].tolist()}
    config = parse_session({**SESSION, "rods": {**SESSION["rods"], "rod": [rod]}}, Path("/l"))

    volume = fit_volume(config, dlts)
    np.testing.assert_allclose(volume.box, (corners.min(axis=0), corners.max(axis=0)))
    np.testing.assert_array_equal(np.unique(volume.hull, axis=0), np.unique(xyz[:108], axis=0))
    assert volume.by == "control points but the wand's images" and not volume.by_labels
