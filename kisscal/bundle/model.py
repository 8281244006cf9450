"""Projection of wand and control points with its analytic Jacobian, for the adjustment.

The state of an adjustment is every camera's intrinsics, rotation, translation and lens,
and every field's wand centre and direction. Derivatives are taken with respect to
increments: a rotation increment ``w`` left-multiplies the current rotation
(``R <- exp([w]x) R``) and a wand direction moves in its tangent plane
(``d <- normalise(d + a e1 + b e2)``), so every derivative is evaluated at a zero
increment and no angle parametrisation ever meets a singularity (Triggs et al. 2000,
section 2.2).

Per observation the chain is ``X -> x = R X + t -> (x1/x3, x2/x3) -> Brown -> K``; the
Jacobian rows are ``d(u, v)`` by the 16 camera unknowns
``fu fv u0 v0 skew | w1 w2 w3 | t1 t2 t3 | k1 k2 p1 p2 k3`` and by the point ``X``.

References
----------
Triggs, B., McLauchlan, P. F., Hartley, R. I., & Fitzgibbon, A. W. (2000). Bundle
adjustment - a modern synthesis. LNCS 1883.
Brown, D. C. (1971). Close-range camera calibration. Photogramm. Eng. 37(8).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from kisscal.camera import Camera, distort, distortion_jacobian, rotation_matrices

#: Unknowns of one camera, in Jacobian column order.
CAMERA_UNKNOWNS: tuple[str, ...] = (
    "fu",
    "fv",
    "u0",
    "v0",
    "skew",
    "w1",
    "w2",
    "w3",
    "t1",
    "t2",
    "t3",
    "k1",
    "k2",
    "p1",
    "p2",
    "k3",
)
N_CAMERA = len(CAMERA_UNKNOWNS)
N_WAND = 5  # centre (3) and two tangent moves of the direction


@dataclass(frozen=True)
class State:
    """Cameras and wand poses of an adjustment, as arrays.

    Attributes
    ----------
    intrinsics : ndarray, shape (C, 5)
        ``fu fv u0 v0 skew`` per camera.
    R : ndarray, shape (C, 3, 3)
    t : ndarray, shape (C, 3)
    lens : ndarray, shape (C, 5)
        ``k1 k2 p1 p2 k3``.
    centre_mm : ndarray, shape (F, 3)
    direction : ndarray, shape (F, 3)
        Unit vectors.
    """

    intrinsics: NDArray[np.float64]
    R: NDArray[np.float64]
    t: NDArray[np.float64]
    lens: NDArray[np.float64]
    centre_mm: NDArray[np.float64]
    direction: NDArray[np.float64]

    @classmethod
    def of(
        cls,
        cameras: tuple[Camera, ...],
        centre_mm: NDArray[np.float64],
        direction: NDArray[np.float64],
    ) -> State:
        intr = np.array([[c.K[0, 0], c.K[1, 1], c.K[0, 2], c.K[1, 2], c.K[0, 1]] for c in cameras])
        d = np.asarray(direction, dtype=float)
        return cls(
            intr,
            np.stack([c.R for c in cameras]),
            np.stack([c.t for c in cameras]),
            np.stack([c.lens for c in cameras]),
            np.asarray(centre_mm, dtype=float).reshape(-1, 3),
            d / np.linalg.norm(d, axis=1, keepdims=True),
        )

    def cameras(self) -> tuple[Camera, ...]:
        out = []
        for i in range(len(self.R)):
            fu, fv, u0, v0, s = self.intrinsics[i]
            K = np.array([[fu, s, u0], [0.0, fv, v0], [0.0, 0.0, 1.0]])
            out.append(Camera(K, self.R[i].copy(), self.t[i].copy(), self.lens[i].copy()))
        return tuple(out)

    def moved(self, d_camera: NDArray[np.float64], d_wand: NDArray[np.float64]) -> State:
        """The state after increments ``(C, 16)`` for the cameras and ``(F, 5)`` for the wand."""
        e1, e2 = tangent_frame(self.direction)
        d = self.direction + d_wand[:, 3:4] * e1 + d_wand[:, 4:5] * e2
        return State(
            self.intrinsics + d_camera[:, 0:5],
            rotation_matrices(d_camera[:, 5:8]) @ self.R,
            self.t + d_camera[:, 8:11],
            self.lens + d_camera[:, 11:16],
            self.centre_mm + d_wand[:, :3],
            d / np.linalg.norm(d, axis=1, keepdims=True),
        )


def tangent_frame(direction: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """Two unit vectors perpendicular to each direction and to each other, shape (F, 3) each."""
    helper = np.where(np.abs(direction[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    e1 = np.cross(direction, helper)
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    return e1, np.cross(direction, e1)


def _skew_matrices(v: NDArray[np.float64]) -> NDArray[np.float64]:
    out = np.zeros((len(v), 3, 3))
    out[:, 0, 1], out[:, 0, 2], out[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    out[:, 1, 0], out[:, 2, 0], out[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    return out


def project(
    state: State, camera: NDArray[np.int64], xyz_mm: NDArray[np.float64], jacobian: bool = True
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.float64] | None]:
    """Pixels of each row's point in its camera, with the Jacobians when asked.

    Returns
    -------
    uv : ndarray, shape (n, 2)
    d_camera : ndarray, shape (n, 2, 16) or None
        By the camera unknowns (:data:`CAMERA_UNKNOWNS`).
    d_point : ndarray, shape (n, 2, 3) or None
        By the lab point.
    """
    intr = state.intrinsics[camera]
    lens = state.lens[camera]
    R = state.R[camera]
    Y = np.einsum("nij,nj->ni", R, xyz_mm)
    xc = Y + state.t[camera]
    inv_z = 1.0 / xc[:, 2]
    xn = xc[:, :2] * inv_z[:, None]
    xd = distort(lens, xn)
    fu, fv, u0, v0, s = intr.T
    uv = np.column_stack([fu * xd[:, 0] + s * xd[:, 1] + u0, fv * xd[:, 1] + v0])
    if not jacobian:
        return uv, None, None
    n = len(camera)
    x, y = xn[:, 0], xn[:, 1]
    r2 = x * x + y * y
    D = distortion_jacobian(lens, xn)  # d(xd, yd) / d(x, y)
    A = np.zeros((n, 2, 2))  # d(u, v) / d(xd, yd)
    A[:, 0, 0], A[:, 0, 1], A[:, 1, 1] = fu, s, fv
    P = np.zeros((n, 2, 3))  # d(x, y) / d(camera-frame point)
    P[:, 0, 0] = P[:, 1, 1] = inv_z
    P[:, 0, 2] = -x * inv_z
    P[:, 1, 2] = -y * inv_z
    d_xc = A @ D @ P  # (n, 2, 3)
    J = np.zeros((n, 2, N_CAMERA))
    J[:, 0, 0], J[:, 1, 1] = xd[:, 0], xd[:, 1]
    J[:, 0, 2] = J[:, 1, 3] = 1.0
    J[:, 0, 4] = xd[:, 1]
    J[:, :, 5:8] = -d_xc @ _skew_matrices(Y)
    J[:, :, 8:11] = d_xc
    r4 = r2 * r2
    lens_d = np.empty((n, 2, 5))  # d(xd, yd) / d(k1 k2 p1 p2 k3)
    lens_d[:, 0, 0], lens_d[:, 1, 0] = x * r2, y * r2
    lens_d[:, 0, 1], lens_d[:, 1, 1] = x * r4, y * r4
    lens_d[:, 0, 2], lens_d[:, 1, 2] = 2 * x * y, r2 + 2 * y * y
    lens_d[:, 0, 3], lens_d[:, 1, 3] = r2 + 2 * x * x, 2 * x * y
    lens_d[:, 0, 4], lens_d[:, 1, 4] = x * r4 * r2, y * r4 * r2
    J[:, :, 11:16] = A @ lens_d
    return uv, J, d_xc @ R


def wand_points(
    state: State, field: NDArray[np.int64], offsets: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Lab position of each row's wand marker (``offsets`` per row, mm), shape (n, 3)."""
    return state.centre_mm[field] + offsets[:, None] * state.direction[field]


def wand_jacobian(
    state: State,
    field: NDArray[np.int64],
    offsets: NDArray[np.float64],
    d_point: NDArray[np.float64],
) -> NDArray[np.float64]:
    """d(u, v) by the five wand unknowns of each row's field, shape (n, 2, 5)."""
    e1, e2 = tangent_frame(state.direction[field])
    J = np.empty((len(field), 2, N_WAND))
    J[:, :, :3] = d_point
    J[:, :, 3] = np.einsum("nij,nj->ni", d_point, e1) * offsets[:, None]
    J[:, :, 4] = np.einsum("nij,nj->ni", d_point, e2) * offsets[:, None]
    return J
