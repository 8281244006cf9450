"""A known target matched automatically from a few clicked points (seeds).

For each camera: a first projection of the target from the seeds (for a
three-dimensional target every pinhole camera the seeds fit, from a resection with the
principal point at the image centre, :mod:`kisscal.target.resect`; a plane homography
for a flat one), then rounds of projecting every target point, matching each to the
nearest dot found in the image and fitting again from every match, until the matches
stop changing. A match must be close (within ``gate`` of the distance to the
neighbouring target point's image), unambiguous (the next dot much farther) and mutual
(no other target point's image nearer to that dot), so that a wrong match needs a wrong
projection by nearly half a dot spacing. When the seeds leave the camera open (a
near-flat part of the target under a narrow view fits a mirrored pose as well) every
camera they fit is matched and the one that matches most is kept. The last rounds add
the terms the held-out points ask for (principal point, pixel aspect, Brown lens terms)
and match once more, which brings in the image corners where a pinhole is a few pixels
off.

Four seeds are the least: the pinhole camera of a resection is 7 numbers (focal length,
rotation, position) and each seed gives two. A narrow view whose centre lies far off the
image's (a split or cropped image) fits no centred camera; from six seeds on, its
principal point and pixel aspect are freed from the start
(:func:`kisscal.target.resect.off_centre`).

References
----------
Abdel-Aziz, Y. I., & Karara, H. M. (1971). Direct linear transformation from comparator
coordinates into object space coordinates in close-range photogrammetry.
Hartley, R., & Zisserman, A. (2004). Multiple View Geometry in Computer Vision (2nd ed.).
Brown, D. C. (1971). Close-range camera calibration. Photogramm. Eng. 37(8).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from kisscal._shared import as_points, in_image, rms_px
from kisscal.camera import Camera
from kisscal.dlt.linear import spread_ratio
from kisscal.dlt.params import DEFAULT_PARAMS as DLT_DEFAULTS
from kisscal.dlt.params import DltParams
from kisscal.errors import EstimationFailed
from kisscal.target.params import DEFAULT_PARAMS, TargetParams
from kisscal.target.resect import (
    NEAR_FLAT,
    OFF_CENTRE_TERMS,
    CameraFit,
    choose_camera,
    off_centre,
    off_centre_hint,
    refine,
    resect,
)
from kisscal.target.seeds import MIN_SEEDS, clicked, too_few_seeds

Projector = Callable[[NDArray[np.float64]], NDArray[np.float64]]

#: Matches needed before the camera model beyond the pinhole is chosen.
MIN_MATCHES = 12
#: Cameras the seeds fit that are each matched (the best few).
_MAX_CANDIDATES = 4


@dataclass(frozen=True)
class TargetMatch:
    """One camera's target points matched to its dots.

    Attributes
    ----------
    dot : ndarray of int, shape (n_target,)
        Index of each target point's dot, -1 where unmatched.
    visible : ndarray of bool, shape (n_target,)
        Target points the final camera projects inside the image.
    camera : Camera
        The camera fitted to every match (lens included).
    rms_px : float
        RMS reprojection residual of the matches (``sqrt(mean(du² + dv²))``).
    seed_rms_px : float
        RMS residual of the seeds under the first model.
    iterations : int
    terms : tuple of str
        Terms beyond the pinhole the held-out matches asked for
        (:data:`kisscal.target.resect.TERM_SIZES`).
    held_out_px : dict
        Held-out RMS error (px) of each camera model compared (see
        :func:`kisscal.target.resect.choose_camera`).
    """

    dot: NDArray[np.int64]
    visible: NDArray[np.bool_]
    camera: Camera
    rms_px: float
    seed_rms_px: float
    iterations: int
    terms: tuple[str, ...] = ()
    held_out_px: dict[str, float] = field(default_factory=dict)

    @property
    def matched(self) -> NDArray[np.bool_]:
        return self.dot >= 0


def is_planar(xyz_mm: ArrayLike, dlt: DltParams = DLT_DEFAULTS) -> bool:
    """True when points lie in one plane (a DLT cannot be fitted to them): their spread
    ratio is below ``dlt.min_spread_ratio``."""
    return spread_ratio(xyz_mm) < dlt.min_spread_ratio


def is_collinear(xyz_mm: ArrayLike, dlt: DltParams = DLT_DEFAULTS) -> bool:
    """True when points lie on one line (no camera can be fitted to them): their second
    spread is below ``dlt.min_spread_ratio`` times the first."""
    xyz = np.asarray(xyz_mm, dtype=float)
    spread = np.linalg.svd(xyz - xyz.mean(axis=0), compute_uv=False)
    return len(spread) < 2 or not spread[1] >= dlt.min_spread_ratio * spread[0]


def _plane(xyz: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Origin and rows (in-plane x, in-plane y, normal) of the best plane of points."""
    origin = xyz.mean(axis=0)
    basis = np.linalg.svd(xyz - origin)[2]
    if np.linalg.det(basis) < 0:
        basis[2] = -basis[2]
    return origin, basis


@dataclass(frozen=True)
class _Start:
    """One first model of the target's image: its projection and, for a 3D target, its
    camera (refitted during the matching rounds)."""

    project: Projector
    camera: Camera | None
    seed_rms_px: float
    terms: tuple[str, ...] = ()  # free beyond the pinhole from the start (off-centre view)


def seed_models(
    seeds_uv: NDArray[np.float64],
    seeds_xyz: NDArray[np.float64],
    target_xyz: NDArray[np.float64],
    size_px: tuple[int, int],
    camera: str,
    params: TargetParams = DEFAULT_PARAMS,
    dlt: DltParams = DLT_DEFAULTS,
    rows: NDArray[np.int64] | None = None,
) -> list[_Start]:
    """The first projections of the target the seeds allow, best first; ``rows`` is each
    seed's row in its file (messages name the file's line), by default its index.

    Raises
    ------
    KisscalError
        Fewer than :data:`MIN_SEEDS` seeds, seeds on one line, or seeds that no single
        camera fits (rms beyond ``seed_tol_px``, the worst seed named).
    """
    where = f"camera {camera}: "
    few = too_few_seeds(len(seeds_uv))
    if few:
        raise EstimationFailed(where + few)
    if is_collinear(seeds_xyz, dlt):
        raise EstimationFailed(
            f"{where}the seeds lie on one line of the target; click points spread over it"
        )
    if is_planar(target_xyz, dlt):
        proj = _homography(seeds_xyz, seeds_uv, camera)
        starts = [_Start(proj, None, rms_px(proj(seeds_xyz) - seeds_uv))]
    else:
        cams = resect(seeds_xyz, seeds_uv, size_px)
        if not cams:
            raise EstimationFailed(
                f"{where}no camera puts the {len(seeds_uv)} seeds where they were clicked; "
                "check each click is on the point its x_mm,y_mm,z_mm name"
            )
        starts = [_Start(c.project, c, rms_px(c.project(seeds_xyz) - seeds_uv)) for c in cams]
        if starts[0].seed_rms_px > params.seed_tol_px:  # a narrow view off the image centre?
            off = off_centre(seeds_xyz, seeds_uv, size_px)
            fits = [(c, rms_px(c.project(seeds_xyz) - seeds_uv)) for c in off]
            starts = [_Start(c.project, c, r, OFF_CENTRE_TERMS) for c, r in fits] or starts
    err = np.linalg.norm(starts[0].project(seeds_xyz) - seeds_uv, axis=1)
    if starts[0].seed_rms_px > params.seed_tol_px:
        worst = int(np.argmax(err))
        line = (worst if rows is None else int(rows[worst])) + 2  # the header is line 1
        raise EstimationFailed(
            f"{where}the {len(seeds_uv)} seeds contradict each other: no camera puts them "
            f"where they were clicked (rms {starts[0].seed_rms_px:.1f} px; seed row "
            f"{line} is off by {err[worst]:.1f} px); check each click is on the point "
            f"its x_mm,y_mm,z_mm name{off_centre_hint(len(seeds_uv))}"
        )
    return [s for s in starts if s.seed_rms_px <= params.seed_tol_px][:_MAX_CANDIDATES]


def _homography(xyz: NDArray[np.float64], uv: NDArray[np.float64], camera: str) -> Projector:
    """The plane homography of a flat target's points (Hartley & Zisserman 2004, 4.1)."""
    origin, basis = _plane(xyz)
    try:
        H, _ = cv2.findHomography((xyz - origin) @ basis[:2].T, uv, 0)
    except cv2.error:
        H = None
    if H is None or not np.all(np.isfinite(H)):
        raise EstimationFailed(
            f"camera {camera}: the flat target's points do not fit one view of a plane "
            "(are three of them on one line?)"
        )

    def homography(pts: NDArray[np.float64]) -> NDArray[np.float64]:
        q = (pts - origin) @ basis[:2].T
        h = q @ H[:, :2].T + H[:, 2]
        return h[:, :2] / h[:, 2:]

    return homography


def match_points(
    projected_px: NDArray[np.float64], dots_px: NDArray[np.float64], params: TargetParams
) -> NDArray[np.int64]:
    """Each projected target point's dot (-1: none close, unambiguous and mutual)."""
    out = np.full(len(projected_px), -1, dtype=np.int64)
    ok_proj = np.all(np.isfinite(projected_px), axis=1)
    if len(dots_px) < 2 or ok_proj.sum() < 2:
        return out
    idx = np.flatnonzero(ok_proj)
    proj = projected_px[idx]
    spacing = cKDTree(proj).query(proj, k=2)[0][:, 1]
    d, j = cKDTree(dots_px).query(proj, k=2)
    close = d[:, 0] <= params.gate * spacing
    clear = d[:, 1] >= params.ambiguity * d[:, 0]
    back = cKDTree(proj).query(dots_px[j[:, 0]])[1]
    mutual = back == np.arange(len(proj))
    ok = close & clear & mutual
    out[idx[ok]] = j[ok, 0]
    return out


def fit_camera(
    xyz: NDArray[np.float64],
    uv: NDArray[np.float64],
    size_px: tuple[int, int],
    start: Camera | None = None,
    params: TargetParams = DEFAULT_PARAMS,
    terms: tuple[str, ...] | None = None,
    dlt: DltParams = DLT_DEFAULTS,
) -> Camera:
    """A camera fitted to matched points: the pinhole plus ``terms``, or, with ``terms``
    left out, plus the terms the held-out points ask for
    (:func:`kisscal.target.resect.choose_camera`).

    ``start`` is the camera to start from (a resection of the points when left out).

    Raises
    ------
    KisscalError
        Fewer than :data:`MIN_SEEDS` points, or points no camera fits.
    """
    xyz = as_points(xyz, 3, "xyz")
    uv = as_points(uv, 2, "uv")
    if start is None:
        if len(xyz) < MIN_SEEDS or is_collinear(xyz, dlt):
            raise EstimationFailed(
                f"{len(xyz)} points on a line or fewer than {MIN_SEEDS}: no camera to fit"
            )
        found = resect(xyz, uv, size_px)
        if not found:
            raise EstimationFailed(f"no camera fits the {len(xyz)} points")
        start = found[0]
    if terms is not None:
        return refine(xyz, uv, start, size_px, terms)
    return choose_camera(xyz, uv, size_px, start, is_planar(xyz, dlt), params).camera


def match_target(
    target_xyz: ArrayLike,
    seeds_uv: ArrayLike,
    seeds_xyz: ArrayLike,
    dots_px: ArrayLike,
    size_px: tuple[int, int],
    camera: str = "",
    params: TargetParams = DEFAULT_PARAMS,
    dlt: DltParams = DLT_DEFAULTS,
) -> TargetMatch:
    """Match every target point of one camera to its dots, starting from the seeds.

    Parameters
    ----------
    target_xyz : array_like, shape (n, 3)
        Every point of the target (``target.csv``), lab mm.
    seeds_uv, seeds_xyz : array_like, shapes (s, 2), (s, 3)
        The clicked points, at least :data:`MIN_SEEDS` on the image (rows off it, or
        NaN, are no clicks and are left out).
    dots_px : array_like, shape (m, 2)
        The dots found in the camera's images (:mod:`kisscal.target.dots`).
    size_px : (int, int)
        Image width and height.
    camera : str
        Camera id, for messages.
    params : TargetParams
    dlt : DltParams
        ``min_spread_ratio`` tells a flat target (matched through a homography) and seeds
        on one line (refused) from points a camera can be fitted to.

    Raises
    ------
    KisscalError
        Bad seeds (see :func:`seed_models`), or fewer than ``min_matched`` of the target
        points inside the image with a dot near their image matched, or matches that no
        camera fits within ``max_rms_px`` (the message says when near-flat seeds under a
        narrow view are the likely cause).
    """
    target = as_points(target_xyz, 3, "target_xyz")
    dots = as_points(dots_px, 2, "dots_px")
    seeds_uv = as_points(seeds_uv, 2, "seeds_uv")
    seeds_xyz = as_points(seeds_xyz, 3, "seeds_xyz")
    rows = np.flatnonzero(clicked(seeds_uv, size_px))  # the file's lines, for messages
    seeds_uv, seeds_xyz = seeds_uv[rows], seeds_xyz[rows]
    starts = seed_models(seeds_uv, seeds_xyz, target, size_px, camera, params, dlt, rows)
    rounds = [_rounds(target, dots, s, size_px, camera, params, dlt) for s in starts]
    best = max(range(len(rounds)), key=lambda i: (int((rounds[i][0] >= 0).sum()), -i))
    dot, iterations, cam = rounds[best]
    m = dot >= 0
    if m.sum() < MIN_MATCHES:
        raise EstimationFailed(
            f"camera {camera}: only {int(m.sum())} target points matched a dot from the "
            f"seeds; {_why_few(seeds_xyz, starts, size_px)}"
        )
    fit, final = _lens_rounds(target, dots, dot, size_px, cam, params, dlt, starts[best].terms)
    projected = fit.camera.project(target)
    visible = in_image(projected, size_px)
    seen = visible & _dot_near(projected, dots, params)
    m = final >= 0
    if m.sum() < params.min_matched * max(seen.sum(), 1):
        raise EstimationFailed(
            f"camera {camera}: only {int(m.sum())} of the {int(seen.sum())} target points "
            f"with a dot near their image matched one; {_why_few(seeds_xyz, starts, size_px)}"
        )
    res = fit.camera.project(target[m]) - dots[final[m]]
    if rms_px(res) > params.max_rms_px:
        raise EstimationFailed(
            f"camera {camera}: the {int(m.sum())} matches fit no camera (rms "
            f"{rms_px(res):.1f} px); {_why_few(seeds_xyz, starts, size_px)}"
        )
    return TargetMatch(
        final,
        visible,
        fit.camera,
        rms_px(res),
        starts[best].seed_rms_px,
        iterations,
        fit.terms,
        fit.held_out_px,
    )


def _rounds(
    target: NDArray,
    dots: NDArray,
    start: _Start,
    size_px: tuple[int, int],
    camera: str,
    params: TargetParams,
    dlt: DltParams,
) -> tuple[NDArray[np.int64], int, Camera | None]:
    """Project, match and refit until the matches stop changing: the matches, the rounds
    run and the last camera (None for a flat target's homography)."""
    proj, cam = start.project, start.camera
    dot = np.full(len(target), -1, dtype=np.int64)
    iterations = 0
    while iterations < params.max_iterations:
        iterations += 1
        new = match_points(proj(target), dots, params)
        if np.array_equal(new, dot):
            break
        dot = new
        m = dot >= 0
        if m.sum() < 2 * MIN_SEEDS or is_collinear(target[m], dlt):
            continue
        if cam is None:
            proj = _homography(target[m], dots[dot[m]], camera)
        else:
            cam = refine(target[m], dots[dot[m]], cam, size_px, start.terms)
            proj = cam.project
    return dot, iterations, cam


def _why_few(seeds_xyz: NDArray, starts: list[_Start], size_px: tuple[int, int]) -> str:
    """Why the seeds may have matched few points: near-flat seeds that several cameras
    fit alike (under a narrow view they fix neither direction nor distance); otherwise
    the seeds or the dots."""
    flat = spread_ratio(seeds_xyz)
    focal = [float(s.camera.K[0, 0]) for s in starts if s.camera is not None]
    if flat < NEAR_FLAT and focal:
        fov = np.degrees(2 * np.arctan(size_px[0] / (2 * np.array(focal))))
        fits = (
            f"fit cameras of focal length {min(focal):.0f} to {max(focal):.0f} px alike"
            if len(focal) > 1
            else f"fit a narrow view ({fov[0]:.0f} degrees across)"
        )
        if len(focal) > 1 or fov[0] < 30.0:
            return (
                f"the {len(seeds_xyz)} seeds lie nearly in one plane of the target "
                f"(thickness / extent {flat:.2f}) and {fits}: under a narrow view such "
                "seeds fix neither the camera's direction nor its distance; click seeds on "
                "three or more rows or levels of the target, spread over the image"
            )
    return (
        "the seeds may name the wrong points, or the dots are not found "
        "(see [target] dots, contrast)"
    )


def _lens_rounds(
    target: NDArray,
    dots: NDArray,
    dot: NDArray,
    size_px: tuple[int, int],
    cam: Camera | None,
    params: TargetParams,
    dlt: DltParams,
    terms: tuple[str, ...] = (),
) -> tuple[CameraFit, NDArray[np.int64]]:
    """The camera model the matches ask for, matched again with it until the matches
    settle (at most ``max_iterations`` rounds), outliers dropped each round; the model is
    chosen again on the settled matches when they changed. ``terms``: those the start
    already frees (an off-centre view's), kept in every model."""
    m = dot >= 0
    planar = is_planar(target, dlt)
    start = refine(target[m], dots[dot[m]], cam, size_px, terms) if cam is not None else None
    start = start or _resected(target[m], dots[dot[m]], size_px)
    dot = drop_outliers(start.project(target), dots, dot, params)
    m = dot >= 0
    fit = choose_camera(target[m], dots[dot[m]], size_px, start, planar, params, terms)
    chosen_on = dot
    camera = fit.camera
    for _ in range(params.max_iterations):
        again = drop_outliers(
            camera.project(target), dots, match_points(camera.project(target), dots, params), params
        )
        if np.array_equal(again, dot) or (again >= 0).sum() < MIN_MATCHES:
            break
        dot = again
        m = dot >= 0
        camera = refine(target[m], dots[dot[m]], camera, size_px, fit.terms)
    if not np.array_equal(dot, chosen_on):  # the model is chosen again on the final matches
        m = dot >= 0
        return choose_camera(target[m], dots[dot[m]], size_px, camera, planar, params, terms), dot
    return CameraFit(camera, fit.terms, fit.held_out_px), dot


def drop_outliers(
    projected_px: NDArray[np.float64],
    dots_px: NDArray[np.float64],
    dot: NDArray[np.int64],
    params: TargetParams = DEFAULT_PARAMS,
) -> NDArray[np.int64]:
    """``dot`` without the matches whose dot lies farther from the point's projection
    than ``outlier_px`` or ``outlier_sigmas`` robust spreads, whichever is larger."""
    k = np.flatnonzero(dot >= 0)
    if not len(k):
        return dot
    r = np.linalg.norm(projected_px[k] - dots_px[dot[k]], axis=1)
    limit = max(params.outlier_px, params.outlier_sigmas * 1.4826 * float(np.median(r)))
    out = dot.copy()
    out[k[r > limit]] = -1
    return out


def _resected(xyz: NDArray, uv: NDArray, size_px: tuple[int, int]) -> Camera:
    found = resect(xyz, uv, size_px)
    if not found:
        raise EstimationFailed(f"no camera fits the {len(xyz)} matched target points")
    return found[0]


def _dot_near(
    projected_px: NDArray[np.float64], dots_px: NDArray[np.float64], params: TargetParams
) -> NDArray[np.bool_]:
    """Target points with a dot within the matching gate of their image: those a match
    was possible for (a point hidden behind something in front of the target has none)."""
    if len(dots_px) == 0 or len(projected_px) < 2:
        return np.zeros(len(projected_px), dtype=bool)
    spacing = cKDTree(projected_px).query(projected_px, k=2)[0][:, 1]
    return cKDTree(dots_px).query(projected_px)[0] <= params.gate * spacing
