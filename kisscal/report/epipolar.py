"""Figure of one field: every camera's blobs with the epipolar lines of all other cameras."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import fixed_margins, new_figure
from kisscal.errors import InputError
from kisscal.recon.epipolar import all_fundamentals, epipolar_lines
from kisscal.recon.reconstruct import Points3D

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def clip_lines(lines: NDArray[np.float64], width: int, height: int) -> NDArray[np.float64]:
    """End points (n, 2, 2) of lines ``a u + b v + c = 0`` across a width x height image.

    Lines closer to horizontal are cut at the left and right image edges, the others at the
    top and bottom (the thesis stores v = m u + n and evaluates it at both edges, 3.3.4).
    """
    a, b, c = lines[:, 0], lines[:, 1], lines[:, 2]
    flat = np.abs(b) >= np.abs(a)
    u0, u1 = -0.5, width - 0.5
    v0, v1 = -0.5, height - 0.5
    with np.errstate(divide="ignore", invalid="ignore"):
        ends_flat = [np.column_stack([np.full(len(a), u), -(a * u + c) / b]) for u in (u0, u1)]
        ends_steep = [np.column_stack([-(b * v + c) / a, np.full(len(a), v)]) for v in (v0, v1)]
    return np.where(flat[:, None, None], np.stack(ends_flat, axis=1), np.stack(ends_steep, axis=1))


def _drawn_markers(n_matches: int, max_markers: int) -> list[int]:
    """Matches whose lines are drawn: at most ``max_markers``, spread over the list."""
    if n_matches <= max_markers:
        return list(range(n_matches))
    return sorted({int(k) for k in np.linspace(0, n_matches - 1, max_markers).round()})


def _legend(fig: Figure, any_hidden: bool) -> None:
    from matplotlib.lines import Line2D

    ring = {"marker": "o", "ls": "", "mfc": "none"}
    keys: list[tuple[str, dict]] = [
        (
            "blob matched to a 3D marker (one colour per marker)",
            {**ring, "mec": "tab:blue", "mew": 1.5, "ms": 8},
        ),
        (
            "its epipolar lines from the other cameras (should cross the ring)",
            {"color": "tab:blue", "lw": 1},
        ),
        ("unmatched blob", {"marker": "x", "ls": "", "color": "0.3"}),
        ("epipolar line of an unmatched blob", {"color": "0.6", "lw": 0.6, "ls": ":"}),
    ]
    if any_hidden:
        hidden = "matched blob, lines not drawn (to keep the panel readable)"
        keys.insert(1, (hidden, {**ring, "mec": "0.55", "ms": 6}))
    handles = [Line2D([], [], label=label, **style) for label, style in keys]
    fig.legend(handles=handles, loc="lower center", ncol=2, fontsize=8, frameon=False)


def zoom_window(
    uv: NDArray[np.float64], width: int, height: int, margin_px: float = 30.0
) -> tuple[float, float, float, float]:
    """(u0, u1, v0, v1) around the blobs, shaped like the image and inside it.

    Examples
    --------
    >>> [round(x, 1) for x in zoom_window(np.array([[100.0, 100], [140, 120]]), 752, 291)]
    [16.6, 223.4, 70.0, 150.0]
    """
    full = (-0.5, width - 0.5, -0.5, height - 0.5)
    if len(uv) == 0:
        return full
    ratio = width / height
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    margin = max(margin_px, 0.25 * float((hi - lo).max()))
    half_u = float(max((hi[0] - lo[0]) / 2 + margin, ((hi[1] - lo[1]) / 2 + margin) * ratio))
    if 2 * half_u >= width:
        return full
    half_v = half_u / ratio
    cu = float(np.clip((lo[0] + hi[0]) / 2, half_u - 0.5, width - 0.5 - half_u))
    cv = float(np.clip((lo[1] + hi[1]) / 2, half_v - 0.5, height - 0.5 - half_v))
    return cu - half_u, cu + half_u, cv - half_v, cv + half_v


def _panels(rows: int, cols: int, titled: bool) -> Figure:
    """The figure of ``rows`` x ``cols`` camera panels, its legend below them."""
    size = (6.5 * cols, 0.8 + 2.9 * rows)
    legend_in = 0.75  # the legend's rows below the panels
    margins = (0.45, 0.1, 0.3 + legend_in, 0.3 + (0.3 if titled else 0.0))
    fig = new_figure(*size, constrained=False)
    fig.subplots_adjust(**fixed_margins(size, (rows, cols), margins, (0.45, 0.5)))
    return fig


def _frame(ax: Any, uv: NDArray[np.float64], width: int, height: int) -> None:
    """Zoom on the blobs (where the lines must cross), never beyond the image."""
    u0, u1, v0, v1 = zoom_window(uv, width, height)
    ax.set_xlim(u0, u1)
    ax.set_ylim(v1, v0)  # image y axis points down
    ax.set_aspect("equal")


def epipolar_figure(
    points_per_camera: list[ArrayLike],
    dlts: ArrayLike,
    size_px: list[tuple[int, int]] | tuple[int, int],
    matches: list[dict[int, int]] | None = None,
    camera_ids: list[str] | None = None,
    title: str = "",
) -> Figure:
    """Draw one field in every camera with the epipolar lines of the other cameras' blobs.

    Parameters
    ----------
    points_per_camera : list of array_like, each (n_c, 2)
        Linearised blob centroids of each camera (px).
    dlts : array_like, shape (n_cameras, 11)
    size_px : (width, height) or one per camera
    matches : list of dict, optional
        Output of :func:`kisscal.recon.match_field`. Up to six matched markers get a
        colour each, with their blobs ringed and their epipolar lines drawn in it; with a
        good calibration every line of a colour crosses the ring of that colour. Other
        matched blobs get grey rings; unmatched blobs are crosses with grey dotted lines.
        A legend says so.
    camera_ids : list of str, optional
        Panel titles.
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib  # imported when a figure is drawn
    from matplotlib.collections import LineCollection

    dlts = np.asarray(dlts, dtype=float)
    n_cam = len(dlts)
    if len(points_per_camera) != n_cam:
        raise InputError(f"epipolar figure: {len(points_per_camera)} point lists, {n_cam} cameras")
    sizes = [tuple(size_px)] * n_cam if np.ndim(size_px) == 1 else [tuple(s) for s in size_px]
    pts = [np.asarray(p, dtype=float).reshape(-1, 2) for p in points_per_camera]
    ids = camera_ids or [f"camera {k + 1}" for k in range(n_cam)]
    matches = matches or []
    drawn = _drawn_markers(len(matches), 6)  # more lines only tangle the panels
    cmap = matplotlib.colormaps["tab10"]
    colour_of: dict[tuple[int, int], tuple[float, ...]] = {}
    hidden: set[tuple[int, int]] = set()
    for m, match in enumerate(matches):
        for c, b in match.items():
            if m in drawn:
                colour_of[c, b] = cmap(drawn.index(m) % 10)
            else:
                hidden.add((c, b))
    F = all_fundamentals(dlts)
    cols = 2 if n_cam > 1 else 1
    rows = int(np.ceil(n_cam / cols))
    fig = _panels(rows, cols, bool(title))
    for j in range(n_cam):
        ax = fig.add_subplot(rows, cols, j + 1)
        w, h = sizes[j]
        segs, colours, widths, styles = [], [], [], []
        for i in range(n_cam):
            if i == j or len(pts[i]) == 0:
                continue
            keep = np.array([(i, b) not in hidden for b in range(len(pts[i]))], dtype=bool)
            if not keep.any():
                continue
            segs.append(clip_lines(epipolar_lines(F[i, j], pts[i][keep]), w, h))
            for b in np.flatnonzero(keep):
                known = (i, b) in colour_of
                colours.append(colour_of.get((i, b), (0.6, 0.6, 0.6, 1.0)))
                widths.append(0.9 if known else 0.6)
                styles.append("solid" if known else "dotted")
        if segs:
            ax.add_collection(
                LineCollection(
                    np.concatenate(segs), colors=colours, linewidths=widths, linestyles=styles
                )
            )
        own = [(j, b) for b in range(len(pts[j]))]
        shown = np.array([k in colour_of for k in own], dtype=bool)
        grey = np.array([k in hidden for k in own], dtype=bool)
        free = ~shown & ~grey
        if shown.any():
            edges = [colour_of[k] for k, s in zip(own, shown, strict=True) if s]
            ax.scatter(*pts[j][shown].T, s=60, facecolors="none", edgecolors=edges, linewidths=1.6)
        if grey.any():
            ax.scatter(*pts[j][grey].T, s=30, facecolors="none", edgecolors="0.55", linewidths=1.0)
        if free.any():
            ax.scatter(pts[j][free, 0], pts[j][free, 1], s=25, c="0.3", marker="x")
        _frame(ax, pts[j], w, h)
        ax.set_title(ids[j], fontsize=9)
        ax.tick_params(labelsize=7)
    _legend(fig, bool(hidden))
    if title:
        fig.suptitle(title)
    return fig


def trial_field_figure(
    points: Points3D,
    field_index: int,
    field: ArrayLike,
    camera: ArrayLike,
    uv: ArrayLike,
    dlts: ArrayLike,
    size_px: list[tuple[int, int]] | tuple[int, int],
    camera_ids: list[str] | None = None,
) -> Figure:
    """:func:`epipolar_figure` of one field of a reconstructed trial.

    Parameters
    ----------
    points : Points3D
        Result of :func:`kisscal.recon.reconstruct_trial` on the table (field, camera, uv).
    field_index : int
        The field to draw.
    field, camera, uv : array_like
        The long-format 2D table the points came from (linearised px).
    dlts, size_px, camera_ids
        As for :func:`epipolar_figure`.
    """
    field = np.asarray(field)
    camera = np.asarray(camera)
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    n_cam = len(np.asarray(dlts))
    rows = [np.flatnonzero((field == field_index) & (camera == c)) for c in range(n_cam)]
    local = {int(r): (c, k) for c in range(n_cam) for k, r in enumerate(rows[c])}
    matches: dict[int, dict[int, int]] = {}
    for r, (c, k) in local.items():
        if points.marker[r] >= 0 and not points.stationary[r]:
            matches.setdefault(int(points.marker[r]), {})[c] = k
    n_still = int(sum(points.stationary[r].sum() for r in rows))
    return epipolar_figure(
        [uv[r] for r in rows],
        dlts,
        size_px,
        list(matches.values()),
        camera_ids,
        title=f"field {field_index}: {len(matches)} markers"
        + (f", {n_still} stationary blobs" if n_still else "")
        + " (each camera zoomed on its blobs; linearised px)",
    )
