"""The event table: events.csv rows and the C3D EVENT group layout."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.gait import GaitEvents


def test_rows_are_sorted_with_nearest_fields() -> None:
    ev = GaitEvents.from_times(
        {("right", "foot_off"): [0.612], ("left", "foot_strike"): [0.1049, 1.3]}, 100.0
    )
    assert ev.rows() == [
        {"side": "left", "event": "foot_strike", "field": 10, "time_s": 0.1049},
        {"side": "right", "event": "foot_off", "field": 61, "time_s": 0.612},
        {"side": "left", "event": "foot_strike", "field": 130, "time_s": 1.3},
    ]
    np.testing.assert_array_equal(ev.times("left", "foot_strike"), [0.1049, 1.3])


def test_c3d_event_group_uses_vicon_labels_and_minutes_seconds() -> None:
    ev = GaitEvents.from_times({("left", "foot_off"): [61.25], ("right", "foot_strike"): [2.0]}, 50)
    group = ev.c3d()
    assert group["LABELS"] == ["Foot Strike", "Foot Off"]
    assert group["CONTEXTS"] == ["Right", "Left"]
    np.testing.assert_allclose(group["TIMES"], [[0.0, 1.0], [2.0, 1.25]])


def test_unknown_side_or_event_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown side/event"):
        GaitEvents.from_times({("middle", "foot_off"): [1.0]}, 100.0)
