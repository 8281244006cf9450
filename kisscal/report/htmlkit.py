"""Small HTML building blocks of the report: escaping, numbers, tables, images, badges.

Text is escaped unless it is :class:`Html` (markup built here), so a trial or marker name
can never break the page.
"""

from __future__ import annotations

import base64
import html
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

_BADGE = {"pass": "PASS", "warn": "CHECK", "fail": "FAIL", "none": "n/a"}


class Html(str):
    """Markup that is already safe to insert."""


def esc(value: Any) -> Html:
    """``value`` as safe HTML (markup made here passes unchanged)."""
    if isinstance(value, Html):
        return value
    return Html(html.escape(str(value)))


def join(parts: Iterable[Any], sep: str = "") -> Html:
    return Html(sep.join(esc(p) for p in parts))


def tag(name: str, body: Any = "", **attrs: Any) -> Html:
    """``<name attrs>body</name>``; attribute names ending in ``_`` lose it (``class_``)."""
    text = "".join(
        f' {k.rstrip("_").replace("_", "-")}="{html.escape(str(v), quote=True)}"'
        for k, v in attrs.items()
        if v is not None and v is not False
    )
    return Html(f"<{name}{text}>{esc(body)}</{name}>")


def fmt(value: Any, digits: int = 3) -> str:
    """A value for a table cell: ``digits`` decimals, integers as integers, yes / no, '–'
    if none, the first six items of a list or tuple; text as it is."""
    if isinstance(value, list | tuple):
        return ", ".join(fmt(v, digits) for v in value[:6]) + (" …" if len(value) > 6 else "")
    if value is None:
        return "–"
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return f"{value:,}".replace(",", " ")
    try:
        x = float(value)
    except (TypeError, ValueError):
        return str(value)
    if not math.isfinite(x):
        return "–"
    if x != 0 and abs(x) < 10 ** (-digits):
        return f"{x:.{max(digits - 1, 1)}e}"
    return f"{x:.{digits}f}"


_UNITS = (
    ("_m_s2", " (m/s²)"),
    ("_mm", " (mm)"),
    ("_px", " (px)"),
    ("_hz", " (Hz)"),
    ("_s", " (s)"),
    ("_deg", " (°)"),
    ("_pct", " (%)"),
)
_WORDS = {"rmse": "RMSE", "rms": "RMS", "sd": "SD", "dlt": "DLT", "n": "number of"}


def heading(key: str) -> str:
    """A column heading from an output key: ``rmse_filled_mm`` -> ``RMSE filled (mm)``.

    Examples
    --------
    >>> heading("rmse_filled_mm"), heading("gravity g_m_s2"), heading("n_true_markers")
    ('RMSE filled (mm)', 'gravity g (m/s²)', 'number of true markers')
    """
    unit = ""
    for suffix, text in _UNITS:
        if key.endswith(suffix):
            key, unit = key[: -len(suffix)], text
            break
    words = key.replace("_", " ").split()
    return " ".join(_WORDS.get(w, w) for w in words) + unit


def badge(state: str) -> Html:
    return tag("span", _BADGE.get(state, state), class_=f"badge {state}")


def table(
    headers: Sequence[Any],
    rows: Iterable[Sequence[Any]],
    numeric: Sequence[int] = (),
    class_: str | None = None,
    row_classes: Sequence[str | None] | None = None,
) -> Html:
    """A table; the columns listed in ``numeric`` are right-aligned."""
    num = set(numeric)
    head = join(tag("th", h, class_="num" if i in num else None) for i, h in enumerate(headers))
    body = []
    for r, row in enumerate(rows):
        cells = join(tag("td", c, class_="num" if i in num else None) for i, c in enumerate(row))
        cls = row_classes[r] if row_classes is not None else None
        body.append(tag("tr", cells, class_=cls))
    return tag(
        "table", join([tag("thead", tag("tr", head)), tag("tbody", join(body))]), class_=class_
    )


def png(path: Path | bytes, alt: str, caption: Any = None, width: str | None = None) -> Html:
    """A PNG embedded as a data URI, with an optional caption."""
    data = path if isinstance(path, bytes) else Path(path).read_bytes()
    src = "data:image/png;base64," + base64.b64encode(data).decode()
    img = tag("img", "", src=src, alt=alt, style=f"width:{width}" if width else None)
    img = Html(img.replace("></img>", ">"))
    return tag("figure", join([img, tag("figcaption", caption) if caption else ""]))


def details(summary: Any, body: Any, open_: bool = False) -> Html:
    return tag("details", join([tag("summary", summary), body]), open=open_)


def section(id_: str, title: str, body: Any, note: Any = None, class_: str | None = None) -> Html:
    return tag(
        "section",
        join([tag("h2", title), tag("p", note, class_="note") if note else "", body]),
        id=id_,
        class_=class_,
    )
