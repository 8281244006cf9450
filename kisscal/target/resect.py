"""One camera from points of a known object, with only the model the points can carry.

A long lens looking at a near-flat part of a target does not determine an 11-parameter
DLT (its principal point lands outside the image), so the camera is built up from the
model the points can carry (the reasons, and the rest of the route, are the section
"Known-target calibration" of ``docs/methods.md``):

1. **Resection** (:func:`resect`): a pinhole camera with its principal point at the
   image centre, square pixels and no lens (7 numbers, which 4 points fix), started from
   OpenCV's perspective-n-point solutions over a ladder of focal lengths (SQPnP,
   Terzakis & Lourakis 2020; IPPE, Collins & Bartoli 2014, for near-flat points) and
   refined by least squares (Hartley & Zisserman 2004, ch. 7). Every distinct camera
   that fits is returned, best first.
2. **Terms the held-out points ask for** (:func:`choose_camera`): principal point, pixel
   aspect, Brown's k1, k2, p1 p2, k3 (Brown 1971), added by forward selection, each only
   when the leave-one-point-out reprojection error (Allen 1974) drops by at least
   ``min_gain``; a flat target's principal point stays at the image centre (Zhang 2000).

No OpenCV error reaches the caller: a perspective-n-point call that fails only drops
that start.

References
----------
Terzakis, G., & Lourakis, M. (2020). A consistently fast and globally optimal solution to
the perspective-n-point problem. ECCV.
Collins, T., & Bartoli, A. (2014). Infinitesimal plane-based pose estimation. IJCV 109(3).
Hartley, R., & Zisserman, A. (2004). Multiple View Geometry in Computer Vision (2nd ed.).
Brown, D. C. (1971). Close-range camera calibration. Photogramm. Eng. 37(8).
Allen, D. M. (1974). The relationship between variable selection and data augmentation
and a method for prediction. Technometrics 16(1).
Zhang, Z. (2000). A flexible new technique for camera calibration. IEEE PAMI 22(11).
Abdel-Aziz, Y. I., & Karara, H. M. (1971). Direct linear transformation from comparator
coordinates into object space coordinates in close-range photogrammetry.

Example
-------
>>> import numpy as np
>>> from kisscal.camera import Camera
>>> K = np.array([[900.0, 0, 319.5], [0, 900.0, 239.5], [0, 0, 1]])
>>> true = Camera(K, np.eye(3), np.array([0.0, 0.0, 1000.0]), np.zeros(5))
>>> xyz = np.array([[-100.0, -80, 0], [120, -60, 40], [90, 110, -30], [-70, 90, 60]])
>>> best = resect(xyz, true.project(xyz), (640, 480))[0]
>>> round(float(best.K[0, 0]), 3), bool(np.allclose(best.project(xyz), true.project(xyz)))
(900.0, True)
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points, rms_px
from kisscal.bundle.model import State, project
from kisscal.camera import LENS_TERMS, Camera, rotation_matrices
from kisscal.dlt.linear import solve_dlt_matrix, spread_ratio
from kisscal.target.params import DEFAULT_PARAMS, TargetParams

#: Numbers each optional term adds to the pinhole's 7, in the order they are tried.
TERM_SIZES: dict[str, int] = {
    "principal_point": 2,
    "aspect": 1,
    "k1": 1,
    "k2": 1,
    "p1p2": 2,
    "k3": 1,
}
#: Focal lengths the resection starts from, in image diagonals (fields of view of about
#: 120 degrees down to 2 degrees).
_FOCAL_LADDER = np.geomspace(0.3, 30.0, 21)
#: Points thinner than this (least over largest spread) are near-flat: a view of them
#: may be mirrored, so IPPE's two poses are tried too.
NEAR_FLAT = 0.1
#: Starts refined by least squares, best seed fit first.
_REFINED_STARTS = 8
#: Terms an off-centre view's first camera frees (:func:`off_centre`).
OFF_CENTRE_TERMS = ("principal_point", "aspect")
#: Least points for :func:`off_centre`: a DLT's 11 numbers need 6 (12 equations), which
#: also leave 3 to check the 9 numbers of the camera.
MIN_OFF_CENTRE_POINTS = 6


@dataclass(frozen=True)
class CameraFit:
    """A camera and the model it was chosen from.

    Attributes
    ----------
    camera : Camera
    terms : tuple of str
        The terms beyond the pinhole that the held-out points asked for (keys of
        :data:`TERM_SIZES`).
    held_out_px : dict
        Held-out RMS reprojection error (px) of every model tried, by its name
        (``pinhole``, ``+principal_point`` ...); empty when the terms were given.
    """

    camera: Camera
    terms: tuple[str, ...]
    held_out_px: dict[str, float]


def centre_px(size_px: tuple[int, int]) -> NDArray[np.float64]:
    """The image centre in kisscal's pixels (the top-left pixel's centre is 0, 0)."""
    return np.array([(size_px[0] - 1) / 2, (size_px[1] - 1) / 2])


#: Columns of :func:`kisscal.bundle.model.project`'s Jacobian behind each term.
_TERM_COLUMNS = {"principal_point": [2, 3], "k1": [11], "k2": [12], "p1p2": [13, 14], "k3": [15]}
_LM_ITERATIONS = 100
_LM_TOLERANCE = 1e-6


def _pinhole_reset(cam: Camera, terms: tuple[str, ...], centre: NDArray) -> Camera:
    """``cam`` with every term it does not free at the pinhole's value (principal point at
    the image centre, square pixels, no skew, no lens)."""
    K = cam.K.copy()
    K[0, 1] = 0.0
    if "principal_point" not in terms:
        K[:2, 2] = centre
    if "aspect" not in terms:
        K[1, 1] = K[0, 0]
    keep = np.zeros(len(LENS_TERMS), dtype=bool)
    for term in terms:
        if term in ("k1", "k2", "k3"):
            keep[LENS_TERMS.index(term)] = True
        elif term == "p1p2":
            keep[2:4] = True
    return Camera(K, cam.R, cam.t, np.where(keep, cam.lens, 0.0))


def _linearised(
    cam: Camera, xyz: NDArray, uv: NDArray, terms: tuple[str, ...]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Residuals (projected - observed, flattened) and their Jacobian by the increments
    of log focal length, rotation (left increment), translation and the free terms."""
    state = State.of((cam,), np.zeros((0, 3)), np.zeros((0, 3)))
    proj, J, _ = project(state, np.zeros(len(xyz), dtype=np.int64), xyz)
    fu, fv = cam.K[0, 0], cam.K[1, 1]
    cols = [J[:, :, 0:1] * fu + J[:, :, 1:2] * fv, J[:, :, 5:11]]
    for term in terms:
        cols.append(J[:, :, 1:2] * fv if term == "aspect" else J[:, :, _TERM_COLUMNS[term]])
    return (proj - uv).ravel(), np.concatenate(cols, axis=2).reshape(2 * len(xyz), -1)


def _moved(cam: Camera, step: NDArray[np.float64], terms: tuple[str, ...]) -> Camera:
    """The camera after an increment (see :func:`_linearised`)."""
    K = cam.K.copy()
    K[0, 0] *= np.exp(step[0])
    K[1, 1] *= np.exp(step[0])
    R = rotation_matrices(step[1:4])[0] @ cam.R
    lens = cam.lens.copy()
    i = 7
    for term in terms:
        d = step[i : i + TERM_SIZES[term]]
        if term == "principal_point":
            K[:2, 2] += d
        elif term == "aspect":
            K[1, 1] *= np.exp(d[0])
        else:
            lens[[c - 11 for c in _TERM_COLUMNS[term]]] += d
        i += len(d)
    return Camera(K, R, cam.t + step[4:7], lens)


def n_unknowns(terms: tuple[str, ...]) -> int:
    """Numbers a camera with these terms has: 7 for the pinhole, plus each term's."""
    return 7 + sum(TERM_SIZES[t] for t in terms)


def in_front(cam: Camera, xyz: NDArray[np.float64]) -> bool:
    """True when every point lies in front of the camera."""
    return bool(np.all(xyz @ cam.R[2] + cam.t[2] > 0))


def refine(
    xyz_mm: ArrayLike,
    uv_px: ArrayLike,
    start: Camera,
    size_px: tuple[int, int],
    terms: tuple[str, ...] = (),
) -> Camera:
    """The camera with ``terms`` free that fits the points best, from ``start``.

    Levenberg-Marquardt on the reprojection error (px) with the analytic Jacobian of
    :func:`kisscal.bundle.model.project` (unknowns scaled to unit columns; a step that
    puts a point behind the camera is refused); terms not given are held at the pinhole's values
    (principal point at the image centre, square pixels, no lens).
    """
    xyz = as_points(xyz_mm, 3, "xyz_mm")
    uv = as_points(uv_px, 2, "uv_px")
    cam = _pinhole_reset(start, terms, centre_px(size_px))
    r, J = _linearised(cam, xyz, uv, terms)
    cost, damping = float(r @ r), 1e-3
    for _ in range(_LM_ITERATIONS):
        # columns scaled to unit length and the damped system solved as least squares,
        # not through the normal equations: a long lens makes the principal point and the
        # rotation nearly interchangeable, and squaring that condition loses the step
        norm = np.linalg.norm(J, axis=0)
        norm[norm == 0] = 1.0
        Js = J / norm
        while damping < 1e12:
            augmented = np.vstack([Js, np.sqrt(damping) * np.eye(len(norm))])
            rhs = np.concatenate([-r, np.zeros(len(norm))])
            with np.errstate(all="ignore"):
                step = np.linalg.lstsq(augmented, rhs, rcond=None)[0] / norm
            trial = _moved(cam, step, terms)
            new = float(np.sum((trial.project(xyz) - uv) ** 2))
            if np.isfinite(new) and new < cost and in_front(trial, xyz):
                break
            damping *= 4.0
        else:
            break  # no step lowers the error: a minimum
        done = cost - new <= _LM_TOLERANCE * cost
        cam, cost, damping = trial, new, max(damping / 3.0, 1e-12)
        if done:
            break
        r, J = _linearised(cam, xyz, uv, terms)
    return cam


def _pnp(
    xyz: NDArray[np.float64], uv: NDArray[np.float64], K: NDArray[np.float64], near_flat: bool
) -> list[tuple[NDArray, NDArray]]:
    """Poses (rotation vector, translation) OpenCV finds for one intrinsic matrix.

    SQPnP for any points; for near-flat ones also IPPE on their best plane, which gives
    the two poses a flat view leaves open. A failed call gives no pose.
    """
    poses = _opencv_pnp(xyz, uv, K, cv2.SOLVEPNP_SQPNP)
    if near_flat and len(xyz) >= 4:
        origin = xyz.mean(axis=0)
        basis = np.linalg.svd(xyz - origin)[2]
        if np.linalg.det(basis) < 0:
            basis[2] = -basis[2]
        flat = (xyz - origin) @ basis.T
        flat[:, 2] = 0.0
        for rvec, tvec in _opencv_pnp(flat, uv, K, cv2.SOLVEPNP_IPPE):
            R = cv2.Rodrigues(rvec)[0] @ basis
            poses.append((cv2.Rodrigues(R)[0].ravel(), tvec - R @ origin))
    return poses


def _opencv_pnp(
    xyz: NDArray[np.float64], uv: NDArray[np.float64], K: NDArray[np.float64], flag: int
) -> list[tuple[NDArray, NDArray]]:
    try:
        _, rvecs, tvecs, _ = cv2.solvePnPGeneric(
            np.ascontiguousarray(xyz, dtype=np.float64),
            np.ascontiguousarray(uv, dtype=np.float64),
            K,
            None,
            flags=flag,
        )
    except cv2.error:  # a degenerate configuration for this solver: no pose from it
        return []
    poses = [
        (np.ravel(r).astype(float), np.ravel(t).astype(float))
        for r, t in zip(rvecs, tvecs, strict=True)
    ]
    return [(r, t) for r, t in poses if np.all(np.isfinite(r)) and np.all(np.isfinite(t))]


def resect(xyz_mm: ArrayLike, uv_px: ArrayLike, size_px: tuple[int, int]) -> list[Camera]:
    """Every distinct pinhole camera (principal point at the image centre, square pixels,
    no lens) that fits the points, best first.

    Parameters
    ----------
    xyz_mm : array_like, shape (n, 3)
        Object points, n >= 4, not all on one line.
    uv_px : array_like, shape (n, 2)
        Their images (px).
    size_px : (int, int)
        Image width and height.

    Returns
    -------
    list of Camera
        Cameras with every point in front, sorted by RMS reprojection error; two cameras
        are distinct when they differ by more than a degree in direction or 2 % in focal
        length. Empty when no start converges.
    """
    xyz = as_points(xyz_mm, 3, "xyz_mm")
    uv = as_points(uv_px, 2, "uv_px")
    found: list[tuple[float, Camera]] = []
    for start in _ladder_starts(xyz, uv, size_px, centre_px(size_px)):
        cam = refine(xyz, uv, start, size_px)
        if in_front(cam, xyz) and not any(_same(cam, other) for _, other in found):
            found.append((rms_px(cam.project(xyz) - uv), cam))
    return [cam for _, cam in sorted(found, key=lambda s: s[0])]


def off_centre(xyz_mm: ArrayLike, uv_px: ArrayLike, size_px: tuple[int, int]) -> list[Camera]:
    """Cameras with their principal point and pixel aspect free (:data:`OFF_CENTRE_TERMS`)
    that fit points a centred pinhole does not, best first: a narrow view of a split or
    cropped sensor, whose optical axis meets the image far from its centre.

    The principal point of the points' 11-term DLT (Abdel-Aziz & Karara 1971; its matrix
    split into ``K R`` by an RQ decomposition, Hartley & Zisserman 2004, 6.2.4) is held
    while OpenCV's poses are found over the focal ladder, as :func:`resect` does at the
    image centre, and the best are refined (:func:`refine`). A narrow view leaves the
    principal point and the direction nearly interchangeable, so that a start at the
    image centre does not reach it, and the DLT's own focal length and skew are loose.

    Parameters
    ----------
    xyz_mm : array_like, shape (n, 3)
        Object points, n >= :data:`MIN_OFF_CENTRE_POINTS`, not in one plane (else the
        list is empty).
    uv_px : array_like, shape (n, 2)
    size_px : (int, int)
    """
    xyz = as_points(xyz_mm, 3, "xyz_mm")
    uv = as_points(uv_px, 2, "uv_px")
    if len(xyz) < MIN_OFF_CENTRE_POINTS or spread_ratio(xyz) < NEAR_FLAT:
        return []
    principal = _dlt_principal_point(xyz, uv)
    if principal is None:
        return []
    starts = _ladder_starts(xyz, uv, size_px, principal)
    found = [refine(xyz, uv, cam, size_px, OFF_CENTRE_TERMS) for cam in starts]
    found = [cam for cam in found if in_front(cam, xyz)]
    return sorted(found, key=lambda cam: rms_px(cam.project(xyz) - uv))


def off_centre_hint(n_seeds: int) -> str:
    """What else may make good seeds fit no centred camera, when more seeds would tell."""
    if n_seeds >= MIN_OFF_CENTRE_POINTS:
        return ""
    return (
        f", or the view is narrow and its centre far off the image's (a split or cropped "
        f"image): then click {MIN_OFF_CENTRE_POINTS} seeds or more, not all in one plane"
    )


def _dlt_principal_point(xyz: NDArray[np.float64], uv: NDArray[np.float64]) -> NDArray | None:
    """The principal point (px) of the points' 11-term DLT, or None when degenerate."""
    Pn, T3, T2, _ = solve_dlt_matrix(xyz, uv)
    M = np.linalg.solve(T2, Pn @ T3)[:, :3]
    # M = K R: K's last column is M's rows' products with its third row over its norm
    m3 = float(M[2] @ M[2])
    if not (np.isfinite(m3) and m3 > 0):
        return None
    return np.array([M[0] @ M[2], M[1] @ M[2]]) / m3


def _ladder_starts(
    xyz: NDArray[np.float64],
    uv: NDArray[np.float64],
    size_px: tuple[int, int],
    principal_px: NDArray[np.float64],
) -> list[Camera]:
    """The best :data:`_REFINED_STARTS` poses OpenCV finds over the focal ladder for a
    square-pixel camera with this principal point, best seed fit first."""
    near_flat = spread_ratio(xyz) < NEAR_FLAT
    starts = []
    for f in _FOCAL_LADDER * float(np.hypot(*size_px)):
        K = np.array([[f, 0.0, principal_px[0]], [0.0, f, principal_px[1]], [0.0, 0.0, 1.0]])
        for rvec, tvec in _pnp(xyz, uv, K, near_flat):
            cam = Camera(K, cv2.Rodrigues(rvec)[0], tvec, np.zeros(len(LENS_TERMS)))
            if in_front(cam, xyz):
                starts.append((rms_px(cam.project(xyz) - uv), cam))
    starts.sort(key=lambda s: s[0])
    return [cam for _, cam in starts[:_REFINED_STARTS]]


def _same(a: Camera, b: Camera) -> bool:
    """Two cameras within a degree of direction and 2 % of focal length."""
    cos = np.clip((np.trace(a.R.T @ b.R) - 1.0) / 2.0, -1.0, 1.0)
    return bool(np.degrees(np.arccos(cos)) < 1.0 and abs(np.log(a.K[0, 0] / b.K[0, 0])) < 0.02)


def candidate_terms(params: TargetParams, planar: bool) -> tuple[str, ...]:
    """The terms :func:`choose_camera` tries, in order: principal point (not for a flat
    target), pixel aspect, then the lens terms ``params.lens_terms`` allows."""
    lens = params.lens_terms
    terms = [] if planar else ["principal_point"]
    terms.append("aspect")
    terms += [t for t in ("k1", "k2") if t in lens]
    if "p1" in lens or "p2" in lens:
        terms.append("p1p2")
    if "k3" in lens:
        terms.append("k3")
    return tuple(terms)


def model_name(terms: tuple[str, ...]) -> str:
    """``pinhole`` or ``pinhole+aspect+k1`` ..."""
    return "+".join(("pinhole", *terms))


def held_out_rms(
    xyz: NDArray[np.float64], uv: NDArray[np.float64], cam: Camera, terms: tuple[str, ...]
) -> float:
    """Leave-one-point-out RMS reprojection error (px) of a fitted camera.

    Each point's residual as the camera fitted without it would leave it, to first order
    (the PRESS statistic, Allen 1974): ``e_i = (I - H_ii)^-1 r_i`` with ``H_ii`` the
    point's 2 x 2 block of the hat matrix ``J (J^T J)^+ J^T`` at the fit. One fit per
    model instead of one per left-out point; a point that alone fixes an unknown (its
    block's eigenvalue 1) makes the model's held-out error infinite.
    """
    r, J = _linearised(cam, xyz, uv, terms)
    norm = np.linalg.norm(J, axis=0)
    norm[norm == 0] = 1.0
    U, sv, _ = np.linalg.svd(J / norm, full_matrices=False)
    U = U[:, sv > sv[0] * 1e-10].reshape(len(xyz), 2, -1)
    keep = np.eye(2) - U @ U.transpose(0, 2, 1)
    det = keep[:, 0, 0] * keep[:, 1, 1] - keep[:, 0, 1] * keep[:, 1, 0]
    if not np.all(det > 1e-9):
        return float("inf")
    res = r.reshape(-1, 2)
    e = np.column_stack(
        [
            (keep[:, 1, 1] * res[:, 0] - keep[:, 0, 1] * res[:, 1]) / det,
            (keep[:, 0, 0] * res[:, 1] - keep[:, 1, 0] * res[:, 0]) / det,
        ]
    )
    return rms_px(e)


def choose_camera(
    xyz_mm: ArrayLike,
    uv_px: ArrayLike,
    size_px: tuple[int, int],
    start: Camera,
    planar: bool,
    params: TargetParams = DEFAULT_PARAMS,
    kept: tuple[str, ...] = (),
) -> CameraFit:
    """The pinhole camera plus the terms that lower the held-out reprojection error.

    Forward selection over :func:`candidate_terms`: each step fits the camera with every
    term not yet kept added in turn and keeps the one whose leave-one-point-out RMS
    (:func:`held_out_rms`) is lowest, when it is lower by at least the fraction
    ``params.min_gain``; a term's worth can show only once another is in (a principal
    point hides behind an unmodelled lens), so every step tries them all again. Models
    need at least twice as many points as unknowns. ``kept``: terms the start already
    needed (an off-centre view's, :func:`off_centre`), kept free from the first fit.
    """
    xyz = as_points(xyz_mm, 3, "xyz_mm")
    uv = as_points(uv_px, 2, "uv_px")
    best = refine(xyz, uv, start, size_px, kept)
    table: dict[str, float] = {}
    if len(xyz) < 2 * n_unknowns(kept):
        return CameraFit(best, kept, table)
    score = table[model_name(kept)] = held_out_rms(xyz, uv, best, kept)
    left = [term for term in candidate_terms(params, planar) if term not in kept]
    while left:
        tried = []
        for term in left:
            trial = (*kept, term)
            if len(xyz) < 2 * n_unknowns(trial):
                continue
            cam = refine(xyz, uv, best, size_px, trial)
            held = table[model_name(trial)] = held_out_rms(xyz, uv, cam, trial)
            tried.append((held, term, cam))
        if not tried:
            break
        held, term, cam = min(tried, key=lambda t: t[0])
        if not held < (1.0 - params.min_gain) * score:
            break
        kept, best, score = (*kept, term), cam, held
        left.remove(term)
    return CameraFit(best, kept, table)
