"""``python -m tests.gait.folder_events``: scoring against force plates, and where the
spread of the errors comes from."""

from __future__ import annotations

import numpy as np

from tests.gait import _real
from tests.gait.folder_events import spread, table


def test_plates_option_scores_against_the_plates_contacts_not_the_marks() -> None:
    """zoo_HC040A14 marks 24 events (plates and Nexus' own) and its plates saw 4 of them:
    with ``by_plates`` the 4 contacts are scored, each one a plate's, none missed, and
    kisscal's foot strikes lie within 30 ms of the plates' (-22 ms mean, 20 N onset)."""
    path = _real.FIXTURES / "zoo_HC040A14.c3d"
    plate_events = _real.read(path, _real.PLATE_GROUP)[3]
    lines = table([path], by_plates=True)
    row = next(line.split() for line in lines if line.startswith("zoo_HC040A14"))
    on_plate = next(line.split() for line in lines if line.startswith("on a plate"))
    assert int(row[1]) == int(on_plate[3]) == sum(len(v) for v in plate_events.values()) == 4
    bias, mean, worst, missed = (float(x) for x in row[2:6])  # kisscal's foot strikes
    assert missed == 0 and abs(worst) < 30.0 and mean == abs(bias)


def test_spread_tells_offsets_between_trials_from_scatter_within_them() -> None:
    """Errors built from known parts: offsets of 40 trials (SD 15 ms), a left foot 6 ms
    later and a right foot 6 ms earlier than their trial, and 3 ms of scatter per event
    (800 events): ``spread`` gives each part back."""
    rng = np.random.default_rng(7)
    trial, event = rng.normal(0.0, 15.0, 40), rng.normal(0.0, 3.0, 800)
    errors = [
        (f"t{i // 20}", side, trial[i // 20] + (6.0 if side == "left" else -6.0) + e)
        for i, e in enumerate(event)
        for side in ["left" if i % 20 < 10 else "right"]
    ]
    total, between, within_trial, within_foot = spread(errors)
    assert abs(within_foot - 3.0) < 0.2  # the per-event scatter alone
    assert abs(within_trial - np.hypot(3.0, 6.0)) < 0.4  # and the feet's offsets
    assert abs(between - np.std(trial)) < 0.5 and total > between
