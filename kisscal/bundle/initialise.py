"""Starting cameras from the wand alone: a camera pair, then every other camera by resection.

With no calibration at all, the wand images give the cameras in the steps of
docs/methods.md, "Wand calibration" (*Alone*): the fundamental matrix of the pair that
sees the wand together most often, the pair's principal distances that reconstruct the
wand with one length in every field (Borghese & Cerveri 2000), then every other camera by
a linear DLT (Woltring & Huiskes 1990), before :mod:`kisscal.bundle.adjust` refines
everything. A symmetric wand's ends cannot be told apart in an image: the midpoint of
its marker images, the image of its centre to a pixel or two, gives a first fundamental
matrix that then decides which end is which in every field.

References
----------
Borghese, N. A., & Cerveri, P. (2000). Calibrating a video camera pair with a rigid bar.
Pattern Recognition 33(1).
Hartley, R., & Zisserman, A. (2004). Multiple View Geometry in Computer Vision, 2nd ed.,
chapters 9-11 (fundamental and essential matrices, RANSAC), 18 (n views).
Nistér, D. (2004). An efficient solution to the five-point relative pose problem.
IEEE PAMI 26(6).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import scipy.optimize
from numpy.typing import NDArray

from kisscal.bundle.adjust import WandObservations, WandPoses, centred_offsets
from kisscal.bundle.find import WandImages
from kisscal.camera import Camera
from kisscal.dlt.camera import decompose_matrix
from kisscal.dlt.linear import solve_dlt_matrix
from kisscal.errors import EstimationFailed

_SEARCH_FIELDS = 150


@dataclass(frozen=True)
class Start:
    """Starting point of the adjustment.

    Attributes
    ----------
    cameras : tuple of Camera
        In the frame of camera ``anchor`` (its axes the frame's), with the origin in the
        middle of the wand's path.
    observations : WandObservations
        Wand images in consistent marker order (fields re-numbered ``0 .. n - 1``).
    wand : WandPoses
        Triangulated wand per field.
    fields : ndarray of int
        The trial field of each wand field.
    anchor : int
        The camera whose pose defines the frame.
    """

    cameras: tuple[Camera, ...]
    observations: WandObservations
    wand: WandPoses
    fields: NDArray[np.int64]
    anchor: int


def overlaps(found: Sequence[WandImages]) -> NDArray[np.int64]:
    """Fields in which each pair of cameras both found the wand, shape (C, C)."""
    n = len(found)
    out = np.zeros((n, n), dtype=np.int64)
    for i in range(n):
        for j in range(n):
            out[i, j] = len(np.intersect1d(found[i].field, found[j].field))
    return out


def start_from_wand(
    found: Sequence[WandImages],
    markers_mm: Sequence[float],
    sizes_px: Sequence[tuple[int, int]],
    cameras: Sequence[str],
    min_fields: int = 20,
) -> Start:
    """Cameras and wand poses from the wand images alone (see the module docstring).

    Parameters
    ----------
    found : sequence of WandImages
        Each camera's wand images (:func:`kisscal.bundle.find.find_wand_images`), raw px.
    markers_mm : sequence of float
        The wand's marker positions.
    sizes_px : sequence of (int, int)
        Image sizes (principal points start at the centres).
    cameras : sequence of str
        Camera ids, for messages.
    min_fields : int
        Fewest fields a camera must share with the cameras placed before it.

    Raises
    ------
    KisscalError
        No two cameras see the wand together in ``min_fields`` fields, or a camera
        cannot be placed (names it and says how many fields it shares).
    """
    common = overlaps(found)
    np.fill_diagonal(common, 0)
    i, j = (int(v) for v in np.unravel_index(int(np.argmax(common)), common.shape))
    if common[i, j] < min_fields:
        raise EstimationFailed(
            f"wand calibration: the wand is in two cameras at once in at most {common[i, j]} "
            f"fields (cameras {cameras[i]} and {cameras[j]}); at least {min_fields} are needed"
        )
    offsets = centred_offsets(markers_mm)
    images = image_table(found)
    ordered = order_table(found, images.shape[1])
    both = np.isfinite(images[i, :, 0, 0]) & np.isfinite(images[j, :, 0, 0])
    ui, uj = images[i, both], images[j, both]
    F, flip = _pair_fundamental(ui, uj, ordered[i, both] & ordered[j, both])
    images[j, np.flatnonzero(both)[flip]] = images[j, np.flatnonzero(both)[flip], ::-1]
    Ki, Kj, R, t = _pair_cameras(F, ui, images[j, both], offsets, sizes_px[i], sizes_px[j])
    placed = {i: Camera(Ki, np.eye(3), np.zeros(3), np.zeros(5))}
    placed[j] = Camera(Kj, R, t, np.zeros(5))
    others = [c for c in range(len(found)) if c not in placed]
    while others:
        wand = triangulate_wand(placed, images)
        known = np.isfinite(wand[:, 0, 0])
        scores = [int(np.sum(known & np.isfinite(images[c, :, 0, 0]))) for c in others]
        c = others.pop(int(np.argmax(scores)))
        if max(scores) < min_fields:
            raise EstimationFailed(
                f"wand calibration: camera {cameras[c]} sees the wand together with the other "
                f"cameras in only {max(scores)} fields; at least {min_fields} are needed"
            )
        placed[c], flip = _resect(images[c], ordered[c], wand, cameras[c])
        images[c, flip] = images[c, flip, ::-1]
    cams = tuple(placed[c] for c in range(len(found)))
    return _start(cams, images, triangulate_wand(placed, images), offsets, i)


def image_table(found: Sequence[WandImages]) -> NDArray[np.float64]:
    """Every camera's wand images in one array, shape (C, fields, k, 2), NaN where absent."""
    n_fields = 1 + max((int(f.field.max()) for f in found if len(f)), default=-1)
    k = found[0].uv_px.shape[1]
    out = np.full((len(found), n_fields, k, 2), np.nan)
    for c, f in enumerate(found):
        out[c, f.field] = f.uv_px
    return out


def order_table(found: Sequence[WandImages], n_fields: int) -> NDArray[np.bool_]:
    """Where each camera's marker order is certain, shape (C, fields)."""
    out = np.zeros((len(found), n_fields), dtype=bool)
    for c, f in enumerate(found):
        out[c, f.field] = f.ordered
    return out


def _pair_fundamental(
    ui: NDArray, uj: NDArray, ordered: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """F of the pair, and the fields where camera ``j``'s marker order must be reversed."""
    flip = np.zeros(len(ui), dtype=bool)
    if not ordered.all():
        F0, _ = cv2.findFundamentalMat(ui.mean(axis=1), uj.mean(axis=1), cv2.FM_RANSAC, 3.0, 0.999)
        if F0 is None or F0.shape != (3, 3):
            raise EstimationFailed(
                "wand calibration: no epipolar geometry fits the first camera pair"
            )
        flip = ~ordered & (_sampson(F0, ui, uj[:, ::-1]) < _sampson(F0, ui, uj))
        uj = np.where(flip[:, None, None], uj[:, ::-1], uj)
    F, _ = cv2.findFundamentalMat(ui.reshape(-1, 2), uj.reshape(-1, 2), cv2.FM_RANSAC, 1.5, 0.9999)
    if F is None or F.shape != (3, 3):
        raise EstimationFailed("wand calibration: no epipolar geometry fits the first camera pair")
    return F, flip


def _sampson(F: NDArray, ui: NDArray, uj: NDArray) -> NDArray[np.float64]:
    """Summed Sampson distances of each field's marker correspondences, shape (n,)."""
    xi = np.concatenate([ui, np.ones((*ui.shape[:2], 1))], axis=2)
    xj = np.concatenate([uj, np.ones((*uj.shape[:2], 1))], axis=2)
    Fx = xi @ F.T
    Ftx = xj @ F
    num = np.einsum("nkj,nkj->nk", xj, Fx) ** 2
    den = Fx[..., 0] ** 2 + Fx[..., 1] ** 2 + Ftx[..., 0] ** 2 + Ftx[..., 1] ** 2
    return (num / den).sum(axis=1)


def _intrinsics(log_f: NDArray[np.float64], size_px: tuple[int, int]) -> NDArray[np.float64]:
    w, h = size_px
    return np.array(
        [[np.exp(log_f[0]), 0.0, (w - 1) / 2], [0.0, np.exp(log_f[1]), (h - 1) / 2], [0, 0, 1]]
    )


def _normalise(K: NDArray, uv: NDArray) -> NDArray[np.float64]:
    return np.column_stack([(uv[:, 0] - K[0, 2]) / K[0, 0], (uv[:, 1] - K[1, 2]) / K[1, 1]])


def _relative_pose(
    F: NDArray, Ki: NDArray, Kj: NDArray, xi: NDArray, xj: NDArray
) -> tuple[NDArray, NDArray, NDArray]:
    """Pose of camera j from ``E = Kj^T F Ki`` and the points it triangulates (|t| = 1)."""
    E = Kj.T @ F @ Ki
    _, R, t, _ = cv2.recoverPose(E, xi.reshape(-1, 1, 2), xj.reshape(-1, 1, 2), np.eye(3))
    X = cv2.triangulatePoints(
        np.hstack([np.eye(3), np.zeros((3, 1))]), np.hstack([R, t]), xi.T, xj.T
    )
    return R, t.ravel(), (X[:3] / X[3]).T


def _pair_cameras(
    F: NDArray,
    ui: NDArray,
    uj: NDArray,
    offsets: NDArray[np.float64],
    size_i: tuple[int, int],
    size_j: tuple[int, int],
) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Intrinsics of the pair and the pose of ``j``, scaled by the wand (see module doc)."""
    if len(ui) > _SEARCH_FIELDS:  # the search needs the wand's spread, not every field
        pick = np.linspace(0, len(ui) - 1, _SEARCH_FIELDS).round().astype(int)
        ui, uj = ui[pick], uj[pick]
    k = ui.shape[1]
    gaps = np.abs(np.diff(offsets))

    def segments(p: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray]:
        Ki, Kj = _intrinsics(p[:2], size_i), _intrinsics(p[2:], size_j)
        R, t, X = _relative_pose(
            F, Ki, Kj, _normalise(Ki, ui.reshape(-1, 2)), _normalise(Kj, uj.reshape(-1, 2))
        )
        seg = np.linalg.norm(np.diff(X.reshape(-1, k, 3), axis=1), axis=2) / gaps
        return seg, R, t

    def residual(p: NDArray[np.float64]) -> NDArray[np.float64]:
        logs = np.log(np.maximum(segments(p)[0], 1e-12))
        return (logs - np.median(logs)).ravel()

    side = max(*size_i, *size_j)
    starts = [
        np.log([f * side, f * side * a, f * side, f * side * a])
        for f in (0.7, 1.2, 2.0, 3.5)  # from wide-angle to narrow lenses
        for a in (1.0, 0.5)  # square pixels, or interlaced video fields
    ]
    scores = []
    for p0 in starts:  # one look at each, then Levenberg-Marquardt from the best two
        try:
            scores.append(float(np.sum(residual(p0) ** 2)))
        except (cv2.error, ValueError, np.linalg.LinAlgError):
            scores.append(np.inf)
    best = None
    for pick in np.argsort(scores)[:2]:
        try:
            sol = scipy.optimize.least_squares(residual, starts[pick], loss="soft_l1", f_scale=0.01)
        except (cv2.error, ValueError, np.linalg.LinAlgError):
            continue
        if best is None or sol.cost < best.cost:
            best = sol
    if best is None:
        raise EstimationFailed("wand calibration: the first camera pair could not be placed")
    seg, R, t = segments(best.x)
    return _intrinsics(best.x[:2], size_i), _intrinsics(best.x[2:], size_j), R, t / np.median(seg)


def triangulate_wand(placed: dict[int, Camera], images: NDArray[np.float64]) -> NDArray[np.float64]:
    """Linear triangulation of every wand marker seen by two or more placed cameras.

    Returns
    -------
    ndarray, shape (fields, k, 3)
        NaN where fewer than two placed cameras saw the field (lenses ignored).
    """
    n_fields, k = images.shape[1:3]
    rows = np.zeros((n_fields, k, 2 * len(placed), 4))
    seen = np.zeros(n_fields, dtype=int)
    for slot, (c, cam) in enumerate(placed.items()):
        P = cam.K @ np.hstack([cam.R, cam.t[:, None]])
        P = P / np.linalg.norm(P)
        uv = images[c]
        ok = np.isfinite(uv[:, 0, 0])
        uv = np.where(ok[:, None, None], uv, 0.0)
        rows[:, :, 2 * slot] = (uv[..., :1] * P[2] - P[0]) * ok[:, None, None]
        rows[:, :, 2 * slot + 1] = (uv[..., 1:] * P[2] - P[1]) * ok[:, None, None]
        seen += ok
    out = np.full((n_fields, k, 3), np.nan)
    good = seen >= 2
    if good.any():
        vt = np.linalg.svd(rows[good])[2]
        X = vt[..., -1, :]
        out[good] = X[..., :3] / X[..., 3:]
    return out


def _resect(
    uv: NDArray[np.float64], ordered: NDArray[np.bool_], wand: NDArray[np.float64], camera: str
) -> tuple[Camera, NDArray[np.int64]]:
    """A camera from its wand images of known wand points (linear DLT, outliers dropped).

    Returns the camera and the fields where its marker order must be reversed.
    """
    both = np.flatnonzero(np.isfinite(uv[:, 0, 0]) & np.isfinite(wand[:, 0, 0]))
    img, pts = uv[both], wand[both]
    if not ordered[both].all():  # centres first: they need no marker order
        P = _robust_dlt(pts.mean(axis=1), img.mean(axis=1), camera)
        seen = _project(P, pts)
        direct = np.linalg.norm(seen - img, axis=-1).sum(axis=-1)
        reverse = np.linalg.norm(seen - img[:, ::-1], axis=-1).sum(axis=-1)
        flip = ~ordered[both] & (reverse < direct)
        img = np.where(flip[:, None, None], img[:, ::-1], img)
    else:
        flip = np.zeros(len(both), dtype=bool)
    P = _robust_dlt(pts.reshape(-1, 3), img.reshape(-1, 2), camera)
    K, R, centre = decompose_matrix(P)
    K[0, 1] = 0.0
    return Camera(K, R, -R @ centre, np.zeros(5)), both[flip]


def _robust_dlt(xyz: NDArray, uv: NDArray, camera: str) -> NDArray[np.float64]:
    """Linear DLT (lab -> px matrix), refitted twice without points far beyond the median
    residual (mismatched ends, a poorly triangulated field)."""
    keep = np.ones(len(xyz), dtype=bool)
    P = None
    for factor in (np.inf, 4.0, 3.0):
        if P is not None:
            err = np.linalg.norm(_project(P, xyz) - uv, axis=1)
            keep = err <= factor * np.median(err[keep])
        if keep.sum() < 6:
            raise EstimationFailed(
                f"wand calibration: camera {camera}'s wand images fit no camera position"
            )
        Pn, T3, T2, _ = solve_dlt_matrix(xyz[keep], uv[keep])
        P = np.linalg.solve(T2, Pn @ T3)
    return P


def _project(P: NDArray, xyz: NDArray) -> NDArray[np.float64]:
    h = xyz @ P[:, :3].T + P[:, 3]
    return h[..., :2] / h[..., 2:]


def wand_poses(markers: NDArray[np.float64], offsets: NDArray[np.float64]) -> WandPoses:
    """Least-squares wand centre and direction of marker positions (n, k, 3)."""
    o = offsets - offsets.mean()
    mean = markers.mean(axis=1)
    d = np.einsum("k,nkj->nj", o, markers - mean[:, None]) / np.sum(o * o)
    centre = mean - offsets.mean() * d
    return WandPoses(centre, d / np.linalg.norm(d, axis=1, keepdims=True))


def _start(
    cameras: tuple[Camera, ...],
    images: NDArray[np.float64],
    wand: NDArray[np.float64],
    offsets: NDArray[np.float64],
    anchor: int,
) -> Start:
    fields = np.flatnonzero(np.isfinite(wand[:, 0, 0]))
    cam, fi, m = np.nonzero(np.isfinite(images[:, fields][..., 0]))
    obs = WandObservations(fi, cam, m, images[cam, fields[fi], m])
    poses = wand_poses(wand[fields], offsets)
    # the origin moves from the anchor camera's centre (where no DLT is defined) to the
    # middle of the wand's path
    middle = poses.centre_mm.mean(axis=0)
    moved = tuple(c.transformed(np.eye(3), -middle) for c in cameras)
    poses = WandPoses(poses.centre_mm - middle, poses.direction)
    return Start(moved, obs, poses, fields, anchor)
