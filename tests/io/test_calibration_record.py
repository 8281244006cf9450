"""The typed readers of ``lens_models``, ``dlt/wand.json`` and ``dlt/target.json``."""

from __future__ import annotations

from kisscal.io.calibration_record import LensModels, TargetMatchRecord, TargetRecord, WandRecord


def test_wand_figures_keep_their_type_and_their_group() -> None:
    """Numbers stay as written (an int stays an int: a count is not shown as 200.000), groups
    are prefixed, yes/no and text are not figures, and each camera's columns appear once."""
    doc = {
        "trial": "wand",
        "length_mean_mm": 500.02,
        "fields_used": 200,
        "held_out": {"length_rms_error_mm": 0.8, "note": "x"},
        "axes": {"rms_mm": 1.5, "markers_seen": {"cam1": 4}},
        "kept": "rods",
        "converged": True,
        "cameras": {"cam1": {"rms_px": 0.2, "points": 10}, "cam2": {"k1": 0.1, "rms_px": 0.3}},
    }
    w = WandRecord.read(doc)
    assert w is not None and w.kept == "rods"
    assert w.figures == (
        ("length_mean_mm", 500.02),
        ("fields_used", 200),
        ("held_out_length_rms_error_mm", 0.8),
        ("axes_rms_mm", 1.5),
    )
    assert isinstance(dict(w.figures)["fields_used"], int)
    assert w.camera_columns == ("rms_px", "points", "k1")
    assert WandRecord.read({}) is None and WandRecord.read(None) is None


def test_lens_models_read_the_comparison_and_nothing_else() -> None:
    """The chosen model, the judge and each model's held-out error; None when not compared."""
    models = {
        "dlt": {"model": "11-parameter DLT", "held_out_rms_px": 0.4, "held_out_3d_rms_mm": 1.2},
        "lens": {"model": "DLT + lens", "held_out_rms_px": None, "in_sample_rms_px": 0.1},
    }
    doc = {"L": [0.0] * 11, "lens_models": {"chosen": "dlt", "by": "held-out 3D error"}}
    doc["lens_models"].update(folds=4, models=models)
    m = LensModels.read(doc)
    assert m is not None and (m.chosen, m.by, m.folds) == ("dlt", "held-out 3D error", 4)
    assert m.held_out_rms_px("dlt") == 0.4 and m.held_out_rms_px("lens") is None
    assert m.held_out_rms_px("refined") is None
    assert m.models["dlt"].held_out_3d_rms_mm == 1.2 and m.models["lens"].model == "DLT + lens"
    assert LensModels.read({"L": [0.0] * 11}) is None and LensModels.read(None) is None


def test_target_record_counts_unmatched_points_and_skips_bad_entries() -> None:
    """Unmatched points are counted from their list; a missing figure is None, not 0; a
    camera entry that is not a table is left out; no camera at all is no record."""
    doc = {
        "seconds": 1.2,
        "cameras": {
            "cam1": {"visible": 40, "matched": 38, "unmatched": [3, 9], "rms_px": 0.21},
            "cam2": "broken",
        },
    }
    record = TargetRecord.read(doc)
    assert record is not None
    assert dict(record.cameras) == {"cam1": TargetMatchRecord(40, 38, 2, 0.21, None)}
    assert TargetRecord.read({"cameras": {}}) is None
    assert TargetRecord.read(None) is None
