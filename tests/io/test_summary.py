"""``summary.json``'s held-out figures, read from ``dlt/check.json`` of each route."""

from __future__ import annotations

from kisscal.io.summary import held_out_figures


def test_rods_wand_and_points_give_their_held_out_figures() -> None:
    rods = {
        "rods_in_sample_mean_mm": 0.04,
        "leave_one_rod_out": {"mean_mm": 0.21, "max_mm": 0.35},
        "lens_models": {"chosen": "refined", "held_out_3d_rms_mm": {"dlt": 0.24}},
    }
    got = held_out_figures(rods)
    assert got["route"] == "rods" and got["leave_one_rod_out_mean_mm"] == 0.21
    assert got["camera_model"]["chosen"] == "refined" and "rods_in_sample_mean_mm" not in got
    wand = {
        "route": "wand",
        "kept": "rods",
        "wand_held_out": {"length_rms_error_mm": 0.33},
        "wand_held_out_rods_alone": {"length_rms_error_mm": 0.31},
        "leave_one_rod_out": {"mean_mm": 0.25, "max_mm": 0.4, "rods_alone_mean_mm": 0.21},
    }
    got = held_out_figures(wand)
    assert got["kept"] == "rods" and got["wand_length_rms_error_mm"] == 0.33
    assert got["rods_alone_leave_one_rod_out_mean_mm"] == 0.21
    assert got["rods_alone_wand_length_rms_error_mm"] == 0.31
    points = {"route": "points", "held_out_points": 29, "leave_out_mean_mm": 0.9}
    got = held_out_figures(points)
    assert got["held_out_points"] == 29 and got["held_out_points_mean_mm"] == 0.9
    assert held_out_figures({}) == {}
