"""Thin appendages cut off thick spots: a target dot touching a streak, a fibre or a speck.

Not in Shafiq et al. (2001). On real frames a dot of a calibration target often touches
something thin at the threshold: a scratch, a fibre, a particle's streak, a reflection
along an edge. The union is one group; its centroid is pulled towards the streak, and
when the streak makes it wider or taller than a marker the size limits drop the dot with
it. The dot is thick and the streak thin: a morphological opening of the group by a disc
of a fraction (:data:`OPEN_FRACTION`) of the group's largest inscribed radius keeps the
dot whole and removes the streak (Serra 1982). Each thin piece left over becomes a group
of its own (flag ``detached``), so that the dot's centroid weighs only the dot.

Only groups with a thick body (largest inscribed radius at least :data:`THICK_PX`, a dot
of about six pixels across or more) that are not already one round disc are examined,
and only those whose body left by the opening is a roundish disc are cut (irregular
blobs such as particle images keep their ragged edges). Only the pixels of those
groups are read: one distance transform of their crops
stacked on one canvas, one of the bodies' complement and one labelling of the thin
pieces, whatever their number.

References
----------
Serra, J. (1982). Image Analysis and Mathematical Morphology. Academic Press, London.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

import kisscal.detect.blobs as fl
from kisscal.detect.advanced import Grouping, group_pixels, regroup
from kisscal.detect.centroid import binary_moments
from kisscal.detect.groups import GroupTable, group_canvas
from kisscal.detect.scan import Runs
from kisscal.detect.shape import PIXEL_AREA_VAR, principal_axes

#: Largest major / minor axis ratio (round units) of one round spot.
ROUND_ELONGATION = 1.25
#: Least fraction of its moments' ellipse a round spot's white pixels fill.
ROUND_FILL = 0.85
#: Largest major / minor axis ratio of an opened body (the opening leaves the base of a
#: streak on it, a little more than on a round spot alone).
BODY_ELONGATION = 1.5
#: Radius of the opening disc, in largest inscribed radii of the group.
OPEN_FRACTION = 0.4
#: Least largest inscribed radius (pixels) of a group examined: a thick body.
THICK_PX = 3.0
#: Least share of a group's pixels outside its body for the group to be cut.
THIN_SHARE = 0.15
#: Most thin pieces kept apart per group (more are merged into the last).
MAX_PIECES = 8


def round_outline(
    runs: Runs, table: GroupTable, min_pixels: int, pixel_aspect: float
) -> NDArray[np.bool_]:
    """Groups whose white pixels form one round disc: nearly equal second moments of the
    outline (elongation at most :data:`ROUND_ELONGATION`), which the pixels fill (at
    least :data:`ROUND_FILL` of its ellipse), and at least ``min_pixels`` of them. Grey
    levels inside (a highlight on a target dot) do not matter."""
    m = binary_moments(runs, table)
    major, minor, _, _ = principal_axes(m.var_x, m.var_y, m.cov_xy, pixel_aspect)
    ellipse = 4.0 * np.pi * np.sqrt(major * minor) * pixel_aspect  # its pixels
    return (
        (table.pixels >= min_pixels)
        & (major <= ROUND_ELONGATION**2 * minor)
        & (table.pixels >= ROUND_FILL * ellipse)
    )


def detach_appendages(
    grouping: Grouping,
    table: GroupTable,
    candidates: NDArray[np.bool_],
    min_pixels: int,
    pixel_aspect: float = 1.0,
) -> Grouping:
    """Cut the thin pieces off the thick body of each candidate group (see module).

    Parameters
    ----------
    grouping, table : Grouping, GroupTable
        The groups of one image.
    candidates : ndarray of bool
        Rows of ``table`` examined (large enough to hold a thick body, not round).
    min_pixels : int
        Thin pieces smaller than this are ragged rim and stay with the body; a group is
        cut only when its other thin pieces hold :data:`THIN_SHARE` of its pixels and
        its body is one round disc.
    pixel_aspect : float
        Width / height of a round spot in pixels (the body's roundness).

    Returns
    -------
    Grouping
        The cut groups replaced by their body (part 0) and thin pieces, flagged
        ``detached``; the grouping itself when nothing was cut.
    """
    idx = candidates.nonzero()[0]
    if idx.size == 0:
        return grouping
    reach = math.ceil(OPEN_FRACTION * float(table.height[idx].max()) / 2) + 2
    canvas, top = group_canvas(grouping.runs, table, idx, gap=reach)
    dist = cv2.distanceTransform(canvas, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    crop = np.searchsorted(top, np.arange(canvas.shape[0]), side="right") - 1
    radius = OPEN_FRACTION * np.maximum.reduceat(dist.max(axis=1), top)
    body = dist >= radius[crop][:, None]
    to_body = cv2.distanceTransform((~body).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    thin = (canvas > 0) & (to_body > radius[crop][:, None])
    _, piece, stats, _ = cv2.connectedComponentsWithStats(thin.astype(np.uint8), connectivity=8)
    # pieces smaller than a spot are ragged rim of the body: they stay with it
    small = stats[:, cv2.CC_STAT_AREA] < max(min_pixels, 2)
    small[0] = True
    piece = np.where(small[piece], 0, piece)
    pixels = group_pixels(grouping, table.label[idx])
    slot = pixels.slot
    row = top[slot] + pixels.y - table.y1[idx][slot] + 1
    col = pixels.x - table.x1[idx][slot] + 1
    label = piece[row, col]
    n_thin = np.bincount(slot, label > 0, minlength=idx.size)
    thick = radius >= OPEN_FRACTION * THICK_PX
    cut = thick & (n_thin > 0) & (n_thin >= THIN_SHARE * table.pixels[idx])
    cut &= _round_body(pixels.x, pixels.y, slot, label == 0, idx.size, pixel_aspect)
    if not cut.any():
        return grouping
    part = _rank_pieces(label, slot, idx.size)
    keep = cut[slot]
    pixels = group_pixels(grouping, table.label[idx[cut]])  # the same order, a subsequence
    part = part[keep]
    k = int(part.max()) + 1
    nan = np.full((int(cut.sum()), k), np.nan)
    flag = np.full(nan.shape[0], fl.DETACHED)
    centres = (nan, nan, np.ones_like(nan))  # no rim shared: the pieces are apart
    return regroup(grouping, table.label[idx[cut]], pixels, part, flag, centres)


def _round_body(
    x: NDArray[np.int64],
    y: NDArray[np.int64],
    slot: NDArray[np.int64],
    body: NDArray[np.bool_],
    groups: int,
    pixel_aspect: float,
) -> NDArray[np.bool_]:
    """Whether each group's body is one roundish disc (elongation at most
    :data:`BODY_ELONGATION`, filled as :func:`round_outline` asks): a target dot or a
    marker, not an irregular blob (a particle image, glare) whose thin edges the
    opening would shave off."""
    s = slot[body]
    bx, by = x[body].astype(float), y[body].astype(float)
    n = np.bincount(s, minlength=groups).astype(float)
    safe = np.maximum(n, 1.0)
    mx, my = np.bincount(s, bx, groups) / safe, np.bincount(s, by, groups) / safe
    dx, dy = bx - mx[s], by - my[s]
    var_x = np.bincount(s, dx * dx, groups) / safe + PIXEL_AREA_VAR
    var_y = np.bincount(s, dy * dy, groups) / safe + PIXEL_AREA_VAR
    cov = np.bincount(s, dx * dy, groups) / safe
    major, minor, _, _ = principal_axes(var_x, var_y, cov, pixel_aspect)
    ellipse = 4.0 * np.pi * np.sqrt(major * minor) * pixel_aspect
    return (n > 0) & (major <= BODY_ELONGATION**2 * minor) & (n >= ROUND_FILL * ellipse)


def _rank_pieces(
    label: NDArray[np.int64], slot: NDArray[np.int64], groups: int
) -> NDArray[np.int64]:
    """Each pixel's part within its group: 0 for the body, 1, 2, ... for its thin pieces
    in order of their labels (at most :data:`MAX_PIECES`)."""
    pieces = np.unique(np.stack([slot[label > 0], label[label > 0]]), axis=1)
    owner, ids = pieces
    per = np.bincount(owner, minlength=groups)
    rank = np.arange(ids.size) - (per.cumsum() - per).repeat(per) + 1
    lookup = np.zeros(int(label.max()) + 1, dtype=np.int64)
    lookup[ids] = np.minimum(rank, MAX_PIECES)
    return lookup[label]
