"""The table of stages (:data:`kisscal.session.stages.PIPELINE`) against what a run does:
each declared parameter member exists, each declared output is written, ``kisscal run``
times each stage of the table once per session or trial, and the documentation's table
is the table."""

from __future__ import annotations

import dataclasses
import json
import re
from pathlib import Path

import pytest

from kisscal.detect import DetectionParams
from kisscal.io.config import load_session
from kisscal.io.store import SessionStore, TrialFiles
from kisscal.session.inputs import load_config
from kisscal.session.params import MEMBERS, Overrides
from kisscal.session.runner import TrialRun, TrialStage, run_keyed, run_trial
from kisscal.session.stages import PIPELINE, session_stages
from tests.session.test_every_parameter import _marker_session

ARCHITECTURE = Path(__file__).resolve().parents[2] / "docs" / "architecture.md"


def test_every_stage_declares_real_parameters_and_outputs() -> None:
    assert [s.name for s in PIPELINE] == ["linearise", "calibrate", "reconstruct", "track"]
    for stage in PIPELINE:
        assert stage.params and set(stage.params) <= set(MEMBERS), stage.name
        owner = TrialFiles if stage.per_trial else SessionStore
        for name in stage.outputs:
            assert hasattr(owner, name), f"{stage.name}: {owner.__name__} has no {name}"
    # session stages first: a trial stage never runs before the rig it needs
    per_trial = [s.per_trial for s in PIPELINE]
    assert per_trial == sorted(per_trial)


def _output_paths(store: SessionStore, stage, cameras, trials) -> list[Path]:
    paths = []
    for name in stage.outputs:
        if stage.per_trial:
            for trial in trials:
                member = getattr(store.trial(trial), name)
                paths.append(member() if callable(member) else member)
        else:
            member = getattr(store, name)
            paths += [member(c) for c in cameras] if callable(member) else [member]
    return paths


@pytest.mark.slow
def test_a_run_writes_every_declared_output_and_times_every_stage(processed: Path) -> None:
    config = load_session(processed)
    store = SessionStore(processed)
    trials = [t.name for t in config.trials]
    stages = session_stages(config)
    assert stages == PIPELINE  # a session of images needs them all
    for stage in stages:
        missing = [
            p for p in _output_paths(store, stage, config.camera_ids, trials) if not p.is_file()
        ]
        assert not missing, f"{stage.name} did not write {missing}"
    timings = json.loads(store.summary_path.read_text())["timings"]
    expected = {
        f"{s.name}_{t}_s" if s.per_trial else f"{s.name}_s"
        for s in stages
        for t in (trials if s.per_trial else [""])
    }
    assert set(timings) == expected


def test_a_session_of_c3d_trials_skips_the_calibration_stages(processed: Path) -> None:
    config = load_session(processed)
    trial = dataclasses.replace(config.trials[0], images=None, video=None, c3d="walk.c3d")
    c3d_only = dataclasses.replace(
        config, grid=None, rods=None, wand=None, axes=None, calibration=None, trials=(trial,)
    )
    assert [s.name for s in session_stages(c3d_only)] == ["reconstruct", "track"]


def _file_name(owner: type, name: str) -> str:
    """The file an output of the store names: the first literal of its docstring."""
    doc = getattr(owner, name).__doc__ or ""
    found = re.search(r"``([^`]+)``", doc)
    assert found, f"{owner.__name__}.{name}'s docstring must start with its file name"
    return f"`{found.group(1)}`"


def stage_table() -> str:
    """The table of stages as docs/architecture.md shows it."""
    rows = [
        "| stage | runs | parameters | writes |",
        "|---|---|---|---|",
    ]
    for s in PIPELINE:
        runs = "per trial" if s.per_trial else "once"
        params = ", ".join(f"`[{p}]`" for p in s.params)
        owner = TrialFiles if s.per_trial else SessionStore
        writes = ", ".join(_file_name(owner, name) for name in s.outputs)
        rows.append(f"| `{s.name}` | {runs} | {params} | {writes} |")
    return "\n".join(rows)


def test_the_documented_table_of_stages_is_the_table() -> None:
    assert stage_table() in ARCHITECTURE.read_text(), (
        "docs/architecture.md's table of stages differs from PIPELINE; paste:\n" + stage_table()
    )


def test_the_runner_hands_a_trial_stage_its_blobs_and_keys_it(tmp_path: Path) -> None:
    """``run_trial``: the stage is handed the trial's blobs, detected with the session's
    ``[detection] threshold`` (between the faint and the bright markers: the three bright
    ones of each frame), never the detection settings; a second run finds its output
    current and is not run again, and another threshold runs it again."""
    root = _marker_session(tmp_path, {"threshold": 150})
    handed: list[tuple] = []

    def compute(run: TrialRun, inputs: tuple, blobs: dict) -> str:
        handed.append((run.params.detection, blobs))
        run.files.points3d.parent.mkdir(parents=True, exist_ok=True)
        run.files.points3d.write_text("written\n")
        return "computed"

    stage = TrialStage(
        "probe",
        inputs=lambda run: (),
        output=lambda files: (files.points3d, True),
        cached=lambda run: "cached",
        compute=compute,
        without_blobs=lambda run: "c3d",
    )
    assert run_trial(stage, load_config(root), "walk", workers=1) == "computed"
    detection, blobs = handed[0]
    assert detection == DetectionParams()  # the stage never sees [detection]'s values
    assert sorted(blobs) == ["cam1", "cam2"]
    assert all(len(b) == 4 and all(len(f) == 3 for f in b) for b in blobs.values())
    assert run_trial(stage, load_config(root), "walk", workers=1) == "cached"
    overrides = Overrides(detection={"threshold": 60})
    assert run_trial(stage, load_config(root), "walk", overrides, workers=1) == "computed"
    assert all(len(f) == 6 for b in handed[1][1].values() for f in b)


def test_the_runner_keys_a_session_stage_and_reuses_it_only_while_its_inputs_stand(
    tmp_path: Path,
) -> None:
    """``run_keyed`` (a linearisation, a calibration route): computed on the first run,
    read back while its key stands, computed again when an input changes or when what it
    wrote does not stand (``cached`` None: another route wrote since); without
    ``compute`` it only reads."""
    store, out = SessionStore(tmp_path), tmp_path / "out" / "stage.json"
    calls: list[str] = []

    def compute() -> str:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text("written\n")
        calls.append("computed")
        return "computed"

    source = tmp_path / "input.txt"
    source.write_text("a\n")
    stage = ("probe", [source], {"threshold": 1.0})
    assert run_keyed(store, out, stage, lambda: None) is None  # nothing written yet
    assert run_keyed(store, out, stage, lambda: "cached", compute) == "computed"
    assert run_keyed(store, out, stage, lambda: "cached", compute) == "cached"
    assert run_keyed(store, out, stage, lambda: "cached") == "cached"
    assert run_keyed(store, out, stage, lambda: None, compute) == "computed"
    other = ("probe", [source], {"threshold": 2.0})
    assert run_keyed(store, out, other, lambda: "cached", compute) == "computed"
    assert run_keyed(store, out, stage, lambda: "cached") is None  # the key moved on
    assert calls == ["computed"] * 3
