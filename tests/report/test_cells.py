"""The report's one cell formatter (``htmlkit.fmt``): every table cell of the page."""

from __future__ import annotations

from kisscal.report.htmlkit import fmt


def test_numbers_cells_lists_and_missing_values() -> None:
    assert fmt(12345) == "12 345"
    assert fmt(0.12345) == "0.123" and fmt(0.12345, 1) == "0.1"
    assert fmt(0.00012) == "1.20e-04"
    assert fmt(None) == fmt(float("nan")) == "–"
    assert fmt(True) == "yes" and fmt(False) == "no"
    assert fmt("derived") == "derived" and fmt("12") == "12"  # text as it is
    assert fmt((7, 5)) == "7, 5"
    assert fmt(list(range(8))) == "0, 1, 2, 3, 4, 5 …"
    assert fmt([0.5, None]) == "0.500, –"
