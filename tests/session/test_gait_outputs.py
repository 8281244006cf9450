"""The track stage with ``[markers] set`` and ``static``: labels, the static template, gait
outputs per trial (events.csv, spatiotemporal.csv, gait.json, the C3D EVENT group),
none for a trial without feet; scored against the grounded walker's true contacts."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import ezc3d
import numpy as np
import pytest
import tomli_w

from kisscal import session
from kisscal.io.files import read_table, write_table
from kisscal.io.points3d import BASE_COLUMNS
from kisscal.io.summary import summarise
from kisscal.synth.motion import standing_template, walking_trial
from tests.tracking.markerset_acceptance import LOWER

RATE = 100.0
HEIGHT_M = 1.68


def _points(path: Path, xyz: np.ndarray, seed: int) -> None:
    """points3d.csv of true positions (markers, fields, 3) + 0.5 mm noise, NaN dropped."""
    rng = np.random.default_rng(seed)
    m, f = np.nonzero(np.isfinite(xyz[..., 0]))
    pts = xyz[m, f] + rng.normal(0, 0.5, (m.size, 3))
    order = np.argsort(f, kind="stable")
    cols = dict(zip(BASE_COLUMNS[1:4], pts[order].T, strict=True))
    path.parent.mkdir(parents=True, exist_ok=True)
    write_table(
        path,
        {"field": f[order], **cols, "n_cameras": np.full(m.size, 3), "rms_px": np.zeros(m.size)},
    )


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, object]:
    """A session whose trials are already reconstructed: a static trial (the walker
    standing), a walk (the grounded walker, true contacts known) and a stick."""
    root = tmp_path_factory.mktemp("gait") / "s"
    k = HEIGHT_M * 1000 / 1755.0
    rng = np.random.default_rng(1)
    a = np.radians(200.0)
    turn = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    still = (k * standing_template(LOWER)) @ turn.T + [300.0, 200.0, 0.0]
    static = still[:, None, :] + rng.normal(0, 1.0, (len(LOWER), 200, 3))
    walk = walking_trial(
        3, 450, RATE, path_mm=4800, model="grounded", height_m=HEIGHT_M, heading_deg=75.0
    )
    moving = walk.xyz_mm.transpose(1, 0, 2)[[walk.names.index(n) for n in LOWER]]
    f = np.arange(300.0)[:, None]
    stick = np.stack(
        [np.hstack([5 * f, 0 * f, 900 + 0 * f]), np.hstack([5 * f, 500 + 0 * f, 900 + 0 * f])]
    )
    trials = {"static01": static, "walk01": moving, "stick": stick}
    for seed, (name, xyz) in enumerate(trials.items()):
        _points(root / "out" / "trials" / name / "points3d.csv", xyz, seed)
    config = {
        "session": {"name": "gait-test", "rate_hz": RATE},
        "cameras": [{"id": "cam1", "size": [640, 480]}],
        "markers": {"set": "plug-in-gait-lower", "names": list(LOWER), "static": "static01"},
        "trials": [{"name": n, "centroids": f"c/{n}/{{camera}}.csv"} for n in trials],
    }
    (root / "session.toml").write_text(tomli_w.dumps(config))
    return root, walk.truth


@pytest.mark.slow
def test_static_first_then_walk_labelled_with_its_template(lab) -> None:
    root, _ = lab
    log: list[str] = []
    result = session.track(root, "walk01", echo=log.append)
    text = "\n".join(log)
    assert "static trial static01: labelled first" in text
    template = json.loads((root / "out/trials/static01/subject_template.json").read_text())
    assert template["names"] == list(LOWER) and all(template["seen"])
    assert abs(template["height_mm"] - 1000 * HEIGHT_M) <= 60.0
    assert sorted(result.labels) == sorted(LOWER)
    tracking = json.loads((root / "out/trials/walk01/tracking.json").read_text())
    assert tracking["labels_certain"] and tracking["flagged"] == []
    assert tracking["sides_from"] == "anatomy"
    # The static trial is cached: tracking again reads its template.
    log.clear()
    session.track(root, "walk01", echo=log.append)
    assert "template from its outputs (cached)" in "\n".join(log)


@pytest.mark.slow
def test_walk_gets_events_and_parameters_close_to_truth(lab) -> None:
    root, truth = lab
    session.track(root, "walk01")
    tdir = root / "out/trials/walk01"
    events = read_table(tdir / "events.csv", numeric=("field", "time_s"))
    assert (tdir / "events.csv").read_text().splitlines()[0] == "side,event,field,time_s"
    for side in ("left", "right"):
        for event in ("foot_strike", "foot_off"):
            found = events["time_s"][(events["side"] == side) & (events["event"] == event)]
            true = truth.events.times(side, event)
            inside = true[(true > 0.3) & (true < 4.2)]  # full strides only
            err = np.abs(found[:, None] - inside[None]).min(axis=0)
            assert err.max() < 0.010, (side, event, err)
            assert len(found) <= len(true)  # nothing extra
    table = read_table(tdir / "spatiotemporal.csv", numeric=("mean", "sd", "n_strides"))
    mean = {
        (p, s): m for p, s, m in zip(table["parameter"], table["side"], table["mean"], strict=True)
    }
    nominal = truth.nominal()
    assert mean[("cadence", "left")] == pytest.approx(nominal["cadence"], rel=0.01)
    assert mean[("walking_speed", "right")] == pytest.approx(nominal["walking_speed"], rel=0.02)
    gait = json.loads((tdir / "gait.json").read_text())
    assert gait["markers"]["left_heel"] == "LHEE"
    group = ezc3d.c3d(str(tdir / "trajectories.c3d"))["parameters"]["EVENT"]
    assert int(group["USED"]["value"][0]) == len(events["side"])
    summary = summarise(root)["trials"]["walk01"]
    assert summary["gait"]["events"] == gait["events"]
    assert (root / "out/figures/gait_walk01.png").is_file()


@pytest.mark.slow
def test_a_trial_without_feet_gets_no_gait_outputs(lab) -> None:
    root, _ = lab
    session.track(root, "stick")
    tdir = root / "out/trials/stick"
    assert (tdir / "trajectories.csv").is_file()
    for name in ("events.csv", "spatiotemporal.csv", "gait.json"):
        assert not (tdir / name).exists()
    assert "EVENT" not in ezc3d.c3d(str(tdir / "trajectories.c3d"))["parameters"]


@pytest.mark.slow
def test_a_rate_given_too_low_is_named_on_a_walk(lab, tmp_path: Path) -> None:
    """Issue 28: rate_hz = 30 for 50 Hz cameras. The walk's times stretch by 1 / 0.6: its
    cadence (about 66 steps/min) and speed are those of a slow walker, but its steps keep
    their length, and the log asks for the rate; at the true rate it asks nothing."""
    root, _ = lab
    log: list[str] = []
    session.track(root, "walk01", echo=log.append)
    assert not [line for line in log if "rate_hz" in line], log
    wrong = tmp_path / "s"
    shutil.copytree(root, wrong)
    config = (wrong / "session.toml").read_text()
    (wrong / "session.toml").write_text(config.replace(f"{RATE}", f"{0.6 * RATE}"))
    log.clear()
    session.track(wrong, "walk01", echo=log.append)
    doubts = [line for line in log if "rate_hz" in line]
    assert len(doubts) == 1 and "walk ratio" in doubts[0], log
    assert f"rate_hz = {0.6 * RATE:g} right?" in doubts[0]
