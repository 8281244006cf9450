"""Phase 1 for a part of a marker set: the body stood on the template, not its distances.

The average pose's distances (:mod:`~kisscal.tracking.labelling.window`) describe a body
well when the trial holds the whole set; when it holds only part of it (a full-body set
on a file without arm markers, or a file whose other markers belong to another set), the
swap search forces a name on every piece and the foreign pieces drag the rest along. A
shipped set's template is upright (Z up, floor at Z = 0), and so is the lab: the body
can only turn about the vertical and slide on the floor. So:

1. :func:`average_pose`: the window's fields are turned about Z and moved onto each
   other (the pieces are the same in every field; weighted towards pieces that stray
   little, the trunk), and each piece's median taken: a standing pose, in the lab's
   right-handed upright frame (no mirror image to settle);
2. :func:`fit_pose`: that pose is put on the template's floor and turned and slid onto
   the template from 12 headings, alternating a capped one-to-one assignment and a fit;
3. :func:`capped_assignment`: pieces farther than the cap from every free name stay
   unnamed (the cap is the price of leaving a piece unnamed).

The match decides which pieces belong to the set and which of its names they hold;
the swap search then orders those names among those pieces (rigid distances tell a
knee from a thigh marker better than a standing template does).
"""

from __future__ import annotations

import warnings

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

#: Headings (evenly spread) from which each field's fit starts.
HEADINGS = 12
#: Rounds of assignment and fit per heading.
ROUNDS = 8
#: With an upright template: how far (SD, mm) a marker's median height while walking may
#: lie from its template height (a heel rises in swing, knees flex).
HEIGHT_SD_MM = 60.0


def heading_fit(
    source: NDArray, target: NDArray, weight: NDArray | None = None
) -> tuple[NDArray, NDArray]:
    """Rotation about Z and translation that best map ``source`` onto ``target`` (k, 3),
    (weighted) least squares, the vertical kept."""
    w = np.ones(source.shape[0]) if weight is None else weight
    w = w / w.sum()
    cs, ct = w @ source, w @ target
    a, b = source[:, :2] - cs[:2], target[:, :2] - ct[:2]
    h = (a * w[:, None]).T @ b
    angle = np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
    r = _about_z(angle)
    return r, ct - r @ cs


def _about_z(angle: float) -> NDArray[np.float64]:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def capped_assignment(
    points: NDArray, template: NDArray, cap_mm: float
) -> tuple[NDArray[np.int64], NDArray[np.int64], float]:
    """One-to-one points -> template names minimising the squared distances capped at
    ``cap_mm``² (a point left unnamed costs the cap); returns the pairs within the cap and
    the capped cost."""
    cap2 = cap_mm * cap_mm
    d2 = ((points[:, None] - template[None]) ** 2).sum(axis=2)
    rows, cols = linear_sum_assignment(np.minimum(d2, cap2))
    ok = d2[rows, cols] < cap2
    cost = float(np.minimum(d2[rows, cols], cap2).sum() + cap2 * (points.shape[0] - rows.size))
    return rows[ok], cols[ok], cost


def fit_pose(
    points: NDArray, template: NDArray, cap_mm: float, lift: float
) -> tuple[float, NDArray, NDArray]:
    """(capped cost, rotation, translation) of the best heading for a pose's points;
    ``lift`` puts the lab floor at the template's (the vertical shift is held there, so a
    lower body cannot pass for an upper one)."""
    best: tuple[float, NDArray, NDArray] = (np.inf, np.eye(3), np.zeros(3))
    centre = template.mean(axis=0)
    for k in range(HEADINGS):
        r = _about_z(2.0 * np.pi * k / HEADINGS)
        t = np.r_[centre[:2] - (r @ points.mean(axis=0))[:2], lift]
        previous = None
        for _ in range(ROUNDS):
            rows, cols, _ = capped_assignment(points @ r.T + t, template, cap_mm)
            if rows.size < 3 or (key := (rows.tobytes(), cols.tobytes())) == previous:
                break
            previous = key
            r, t = heading_fit(points[rows], template[cols])
            t[2] = lift  # the floor is known: the body does not float up or sink
        cost = capped_assignment(points @ r.T + t, template, cap_mm)[2]
        if cost < best[0]:
            best = (cost, r, t)
    return best


def average_pose(pos: NDArray, rounds: int = 3, lift: bool = True) -> NDArray[np.float64]:
    """The pieces' median position (k, 3) with every field turned about the vertical and
    moved onto the others (NaN for a piece never seen with two others).

    Fields are fitted (heading and translation, the pieces being the same in every field)
    to the field where most pieces are seen, then to the median pose, ``rounds`` times,
    each piece weighted by how little it strays from its median (1 / (spread² + 10²),
    spread in mm): the trunk and pelvis hold the body's frame, the swing of the legs
    averages out, and the pose stays in the lab's upright, right-handed frame (no mirror
    image to settle, unlike distances). Without ``lift`` the fields only slide on the
    floor and every height stays the lab's: a fitted vertical shift moves the pose off
    its heights round after round (a walker's pelvis 13 mm down in three rounds, its feet
    up to 25 mm up), which stood a lower body walking at 1.4 m/s 100 mm short.
    """
    seen = np.isfinite(pos[..., 0])
    pose = pos[:, int(np.argmax(seen.sum(axis=0)))]
    weight = np.ones(pos.shape[0])
    aligned = np.full_like(pos, np.nan)
    for _ in range(rounds):
        for f in range(pos.shape[1]):
            ok = seen[:, f] & np.isfinite(pose[:, 0])
            if ok.sum() >= 3:
                r, t = heading_fit(pos[ok, f], pose[ok], weight[ok])
                t[2] = t[2] if lift else 0.0
                aligned[seen[:, f], f] = pos[seen[:, f], f] @ r.T + t
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # pieces never aligned
            pose = np.nanmedian(aligned, axis=1)
            spread2 = np.nanmean(np.sum((aligned - pose[:, None]) ** 2, axis=2), axis=1)
        weight = 1.0 / (np.nan_to_num(spread2, nan=np.inf) + 100.0)
    return pose


def floor_lift(pos: NDArray, template: NDArray) -> float:
    """Vertical shift putting the lab floor at the template's: where the lowest piece
    spends its lowest tenth of the time goes to the template's lowest marker."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # pieces never seen
        low = np.nanmin(np.nanpercentile(pos[..., 2], 10, axis=1))
    return float(template[:, 2].min() - low)


def fit_on_floor(
    pose: NDArray, pos: NDArray, template: NDArray, cap_mm: float
) -> tuple[float, NDArray, NDArray]:
    """:func:`fit_pose` of ``pose`` (the seen pieces' average pose of ``pos``) on either
    floor, the lower capped cost: the lowest piece on the floor (:func:`floor_lift`),
    or the lab's own (Z = 0, where a calibration puts it) when that lowers the body by
    more than ``cap_mm``.

    The lowest piece stands on the floor only when the feet are in view: an upper body
    (shd01: no leg marker, its wrist 775 mm above the lab floor) put there named its
    head as the pelvis and its trunk as the thighs. A lab whose zero is not its floor
    fits the body worse there, and keeps the first.
    """
    lift = floor_lift(pos, template)
    fits = [fit_pose(pose, template, cap_mm, lift)]
    if lift < -cap_mm:
        fits.append(fit_pose(pose, template, cap_mm, 0.0))
    return min(fits, key=lambda fit: fit[0])


def pose_on_template(
    pos: NDArray, template: NDArray, cap_mm: float
) -> tuple[NDArray[np.float64], bool]:
    """The pieces' average pose (:func:`average_pose`) turned about the vertical and moved
    onto an upright ``template`` (k, 3; NaN for pieces not placed), and whether it stands
    on the lab's own floor rather than on its lowest piece (:func:`fit_on_floor`).

    The pose is put on the template's floor, then fitted from :data:`HEADINGS` headings by
    alternating a capped one-to-one assignment (pieces farther than ``cap_mm`` from every
    free name stay unnamed) and a least-squares fit of heading and translation; the
    heading of lowest capped cost wins.

    References
    ----------
    Kuhn 1955 (the assignment); Besl & McKay 1992 (alternating assignment and fit).
    """
    pose = average_pose(pos)
    seen = np.isfinite(pose[:, 0])
    if seen.sum() < 3:
        return np.full_like(pose, np.nan), False
    _, r, t = fit_on_floor(pose[seen], pos, template, cap_mm)
    return pose @ r.T + t, bool(t[2] == 0.0)


def height_costs(
    dense: NDArray, core: NDArray, rich: NDArray, template: NDArray, lab_floor: bool = False
) -> tuple:
    """Median heights of the core pieces over ``rich``, and each piece's cost of each
    name: its height above the floor against the name's template height, in units of
    :data:`HEIGHT_SD_MM`, squared.

    The floor is where the lowest piece spends its lowest tenth of the time, put at the
    template's lowest marker (the feet's markers sit a few centimetres above the floor);
    with ``lab_floor``, it is the lab's Z = 0 (the feet are not in view,
    :func:`~kisscal.tracking.labelling.upright.fit_on_floor`).
    """
    z = dense[np.ix_(core, rich)][..., 2]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        heights = np.nanmedian(z, axis=1)
        floor = np.nanmin(np.nanpercentile(z, 10, axis=1)) - template[:, 2].min()
    floor = 0.0 if lab_floor else floor
    unary = ((heights - floor)[:, None] - template[None, :, 2]) ** 2 / HEIGHT_SD_MM**2
    return heights, unary
