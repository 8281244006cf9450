"""Figure of one field: every camera's blobs with the epipolar lines of all other cameras."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from numpy.typing import ArrayLike, NDArray

from kisscal.errors import KisscalError
from kisscal.recon.epipolar import all_fundamentals, epipolar_lines
from kisscal.recon.reconstruct import Points3D


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
        ends_flat = np.stack(
            [
                np.column_stack([np.full(len(a), u0), -(a * u0 + c) / b]),
                np.column_stack([np.full(len(a), u1), -(a * u1 + c) / b]),
            ],
            axis=1,
        )
        ends_steep = np.stack(
            [
                np.column_stack([-(b * v0 + c) / a, np.full(len(a), v0)]),
                np.column_stack([-(b * v1 + c) / a, np.full(len(a), v1)]),
            ],
            axis=1,
        )
    return np.where(flat[:, None, None], ends_flat, ends_steep)


def epipolar_figure(
    points_per_camera: list[ArrayLike],
    dlts: ArrayLike,
    size_px: list[tuple[int, int]] | tuple[int, int],
    matches: list[dict[int, int]] | None = None,
    camera_ids: list[str] | None = None,
    title: str = "",
) -> Figure:
    """Draw one field in every camera with the epipolar lines of all other cameras' blobs.

    Parameters
    ----------
    points_per_camera : list of array_like, each (n_c, 2)
        Linearised blob centroids of each camera (px).
    dlts : array_like, shape (n_cameras, 11)
    size_px : (width, height) or one per camera
    matches : list of dict, optional
        Output of :func:`kisscal.recon.match_field`; matched blobs and their lines are
        coloured by marker, unmatched blobs drawn as grey crosses with grey lines.
    camera_ids : list of str, optional
        Panel titles.
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
    """
    dlts = np.asarray(dlts, dtype=float)
    n_cam = len(dlts)
    if len(points_per_camera) != n_cam:
        raise KisscalError(
            f"epipolar figure: {len(points_per_camera)} point lists, {n_cam} cameras"
        )
    sizes = [tuple(size_px)] * n_cam if np.ndim(size_px) == 1 else [tuple(s) for s in size_px]
    pts = [np.asarray(p, dtype=float).reshape(-1, 2) for p in points_per_camera]
    ids = camera_ids or [f"camera {k + 1}" for k in range(n_cam)]
    colour_of: dict[tuple[int, int], tuple[float, ...]] = {}
    cmap = matplotlib.colormaps["tab20"]
    for m, match in enumerate(matches or []):
        for c, b in match.items():
            colour_of[c, b] = cmap(m % 20)
    grey = (0.6, 0.6, 0.6, 1.0)
    F = all_fundamentals(dlts)
    cols = 2 if n_cam > 1 else 1
    rows = int(np.ceil(n_cam / cols))
    fig = Figure(figsize=(6.5 * cols, 2.9 * rows), layout="constrained")
    for j in range(n_cam):
        ax = fig.add_subplot(rows, cols, j + 1)
        w, h = sizes[j]
        segs, colours = [], []
        for i in range(n_cam):
            if i == j or len(pts[i]) == 0:
                continue
            segs.append(clip_lines(epipolar_lines(F[i, j], pts[i]), w, h))
            colours += [colour_of.get((i, b), grey) for b in range(len(pts[i]))]
        if segs:
            ax.add_collection(LineCollection(np.concatenate(segs), colors=colours, linewidths=0.5))
        matched = np.array([(j, b) in colour_of for b in range(len(pts[j]))], dtype=bool)
        if matched.any():
            ax.scatter(
                pts[j][matched, 0],
                pts[j][matched, 1],
                s=45,
                facecolors="none",
                edgecolors=[colour_of[j, b] for b in np.flatnonzero(matched)],
                linewidths=1.5,
            )
        if (~matched).any():
            ax.scatter(pts[j][~matched, 0], pts[j][~matched, 1], s=25, c="0.3", marker="x")
        ax.set_xlim(-0.5, w - 0.5)
        ax.set_ylim(h - 0.5, -0.5)
        ax.set_aspect("equal")
        ax.set_title(ids[j], fontsize=9)
        ax.tick_params(labelsize=7)
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
        + (f", {n_still} stationary blobs" if n_still else ""),
    )
