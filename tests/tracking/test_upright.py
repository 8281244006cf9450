"""The upright match of a part of a marker set (kisscal.tracking.labelling.upright)."""

import numpy as np

from kisscal.markersets import marker_set
from kisscal.tracking.labelling.upright import (
    average_pose,
    capped_assignment,
    heading_fit,
    pose_on_template,
)

FULL = marker_set("plug-in-gait-full")


def _about_z(deg: float) -> np.ndarray:
    a = np.radians(deg)
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1.0]])


def test_heading_fit_recovers_a_turn_about_the_vertical():
    rng = np.random.default_rng(0)
    src = rng.normal(size=(10, 3)) * 300
    r = _about_z(137.0)
    r_fit, t_fit = heading_fit(src, src @ r.T + [100.0, -50.0, 20.0])
    np.testing.assert_allclose(r_fit, r, atol=1e-9)
    np.testing.assert_allclose(t_fit, [100.0, -50.0, 20.0], atol=1e-9)


def test_capped_assignment_leaves_far_points_unnamed():
    template = np.array([[0.0, 0, 0], [500, 0, 0], [0, 500, 0]])
    points = template[[2, 0]] + 5.0
    points = np.vstack([points, [[2000.0, 0, 0]]])
    rows, cols, cost = capped_assignment(points, template, 100.0)
    assert dict(zip(rows.tolist(), cols.tolist(), strict=True)) == {0: 2, 1: 0}
    assert cost == 2 * 75.0 + 100.0**2


def _walking_part(seed: int, keep: list[str], n_foreign: int, heading_deg: float):
    """Fields of a body of the set's template turning slowly about the vertical, with
    legs swinging, only the ``keep`` names and ``n_foreign`` markers of no name."""
    rng = np.random.default_rng(seed)
    rows = [FULL.names.index(n) for n in keep]
    body = FULL.template_mm[rows]
    foreign = FULL.template_mm[rng.choice(len(FULL.names), n_foreign)] + rng.normal(
        0, 60, (n_foreign, 3)
    ) * [1, 1, 0]
    pts = np.vstack([body, foreign])
    swing = np.array([n[1:] in ("KNE", "TIB", "ANK", "HEE", "TOE") for n in keep] + [0] * n_foreign)
    side = np.array([1.0 if n.startswith("L") else -1.0 for n in keep] + [0] * n_foreign)
    fields = []
    for f in range(30):
        phase = np.sin(2 * np.pi * f / 30)
        moved = pts + np.outer(swing * side * phase * 150.0, [1.0, 0, 0])
        r = _about_z(heading_deg + 0.3 * f)
        fields.append(moved @ r.T + [1000.0 + 40 * f, 200.0, 0.0])
    pos = np.stack(fields, axis=1)  # (k, F, 3)
    pos[rng.random(pos.shape[:2]) < 0.1] = np.nan  # some samples missing
    return pos, rows


def test_a_lower_body_with_foreign_markers_stands_on_the_full_body_template():
    lower = [n for n in FULL.names if n[0] in "LR" and n[1:] in
             ("ASI", "PSI", "THI", "KNE", "TIB", "ANK", "HEE", "TOE")]  # fmt: skip
    pos, rows = _walking_part(1, lower, 6, heading_deg=210.0)
    pose, _ = pose_on_template(pos, FULL.template_mm, 120.0)
    found, names, _ = capped_assignment(pose, FULL.template_mm, 120.0)
    named = dict(zip(found.tolist(), names.tolist(), strict=True))
    right = sum(named.get(i) == rows[i] for i in range(len(rows)))
    wrong = [i for i in range(len(rows)) if i in named and named[i] != rows[i]]
    assert right >= len(rows) - 1 and not wrong
    # the average pose is the standing pose: legs' swing averaged out
    pose0 = average_pose(pos)
    assert np.isfinite(pose0).all()


def test_an_upper_body_without_feet_stands_on_the_lab_floor():
    # shd01 (BTK): trunk, head, arms and pelvis, no leg marker. Stood with its lowest
    # piece (a wrist) on the floor, its head took the pelvis' names.
    upper = [n for n in FULL.names if n[1:] not in ("THI", "KNE", "TIB", "ANK", "HEE", "TOE")]
    pos, rows = _walking_part(2, upper, 0, heading_deg=40.0)
    pose, lab_floor = pose_on_template(pos, FULL.template_mm, 120.0)
    found, names, _ = capped_assignment(pose, FULL.template_mm, 120.0)
    named = dict(zip(found.tolist(), names.tolist(), strict=True))
    right = sum(named.get(i) == rows[i] for i in range(len(rows)))
    assert lab_floor and right >= len(rows) - 2
    # 300 mm up in a lab whose zero is not the floor, the feet on it: the lowest piece
    lower = [n for n in FULL.names if n[1:] in ("ASI", "PSI", "KNE", "ANK", "HEE", "TOE")]
    pos, rows = _walking_part(3, lower, 0, heading_deg=40.0)
    assert not pose_on_template(pos + [0.0, 0.0, 300.0], FULL.template_mm, 120.0)[1]
