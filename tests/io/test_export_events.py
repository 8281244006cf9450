"""The C3D EVENT group (Vicon's layout) read back by ezc3d, the c3d package and Kinetics
Toolkit, with the labels, contexts and times written."""

from __future__ import annotations

import warnings
from pathlib import Path

import c3d
import ezc3d
import numpy as np
import pytest

from kisscal.gait.table import GaitEvents
from kisscal.io.export import write_c3d
from kisscal.tracking.tracks import make_tracks

RATE = 100.0
TIMES = {
    ("left", "foot_strike"): [0.1234, 1.2345, 61.5],  # one past a minute: (1, 1.5)
    ("left", "foot_off"): [0.7890, 1.9012],
    ("right", "foot_strike"): [0.6789],
    ("right", "foot_off"): [0.2468, 1.3579],
}


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, GaitEvents]:
    n = 6200  # 62 s at 100 Hz
    field = np.arange(n)
    xyz = np.column_stack([field * 1.0, np.zeros(n), np.full(n, 900.0)])
    tracks = make_tracks(field, np.zeros(n), xyz, np.full_like(xyz, np.nan), np.zeros(n), field)
    events = GaitEvents.from_times(TIMES, RATE)
    path = tmp_path_factory.mktemp("events") / "trajectories.c3d"
    write_c3d(path, tracks, ("SACR",), RATE, events=events)
    return path, events


def _expected(events: GaitEvents) -> list[tuple[str, str, float]]:
    names = {"foot_strike": "Foot Strike", "foot_off": "Foot Off"}
    return [
        (names[str(e)], str(s).capitalize(), float(t))
        for s, e, t in zip(events.side, events.event, events.time_s, strict=True)
    ]


def test_ezc3d_reads_the_vicon_layout(written) -> None:
    path, events = written
    group = ezc3d.c3d(str(path))["parameters"]["EVENT"]
    times = group["TIMES"]["value"]
    assert times.shape == (2, len(events))
    got = list(
        zip(
            group["LABELS"]["value"],
            group["CONTEXTS"]["value"],
            times[0] * 60 + times[1],
            strict=True,
        )
    )
    for (label, context, t), (e_label, e_context, e_t) in zip(got, _expected(events), strict=True):
        assert (label, context) == (e_label, e_context)
        assert t == pytest.approx(e_t, abs=1e-5)  # stored as 32-bit floats
    assert int(group["USED"]["value"][0]) == len(events)
    assert times[0].max() == 1.0 and times[1].max() < 60.0  # minutes, then seconds
    icons = dict(zip(group["LABELS"]["value"], group["ICON_IDS"]["value"], strict=True))
    assert icons == {"Foot Strike": 1, "Foot Off": 2}
    assert (
        "heel strikes" in group["DESCRIPTIONS"]["value"][0]
        or "toe leaves" in (group["DESCRIPTIONS"]["value"][0])
    )


def test_the_c3d_package_reads_the_same_events(written) -> None:
    path, events = written
    with warnings.catch_warnings(), path.open("rb") as handle:
        warnings.simplefilter("ignore")
        group = c3d.Reader(handle).get("EVENT")
        labels = [s.strip() for s in group.get("LABELS").string_array]
        contexts = [s.strip() for s in group.get("CONTEXTS").string_array]
        times = group.get("TIMES").float_array
    assert list(zip(labels, contexts, strict=True)) == [(a, b) for a, b, _ in _expected(events)]
    np.testing.assert_allclose(times[:, 0] * 60 + times[:, 1], events.time_s, atol=1e-5)


def test_kinetics_toolkit_reads_the_events(written) -> None:
    import kineticstoolkit as ktk  # the test extra's; imported here, it is slow to load

    path, events = written
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        points = ktk.read_c3d(str(path), include_event_context=True)["Points"]
    got = sorted((e.name, e.time) for e in points.events)
    want = sorted((f"{c}:{label}", t) for label, c, t in _expected(events))
    assert [g[0] for g in got] == [w[0] for w in want]
    np.testing.assert_allclose([g[1] for g in got], [w[1] for w in want], atol=1e-5)
    # The events sit on the trajectories' time axis: field k at k / rate.
    assert points.time[0] == 0.0 and points.time[1] == pytest.approx(1 / RATE)


def test_no_events_no_event_group(tmp_path: Path) -> None:
    field = np.arange(10)
    xyz = np.zeros((10, 3))
    tracks = make_tracks(field, np.zeros(10), xyz, xyz, np.zeros(10), field)
    path = write_c3d(
        tmp_path / "t.c3d", tracks, ("A",), RATE, events=GaitEvents.from_times({}, RATE)
    )
    assert "EVENT" not in ezc3d.c3d(str(path))["parameters"]
