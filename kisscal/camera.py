"""kisscal's one camera model: pinhole geometry, lens, projection and the exchange forms.

A :class:`Camera` maps a lab point ``X`` (mm) to camera coordinates ``x = R X + t``
(z along the optical axis, y down the image), to normalised coordinates
``(xn, yn) = (x1 / x3, x2 / x3)`` and, through ``K = [[fu, s, u0], [0, fv, v0], [0, 0, 1]]``
(principal distances along u and v, hence the pixel aspect, skew and principal point), to
the *ideal* pixels ``K (xn, yn, 1)``: the DLT camera L1..L11 (Abdel-Aziz & Karara 1971;
Woltring & Huiskes 1990, eq. 15).

Its lens is what lies between the ideal pixels and the raw ones an image shows, in up to
three layers, each the identity when absent:

- Brown's distortion of the normalised coordinates (Brown 1966, 1971), in OpenCV's order
  and convention (Bradski 2000): radial ``k1 k2 p1 p2 k3``, then the rational model's
  ``k4 k5 k6`` and the thin prism's ``s1 s2 s3 s4``. The bundle adjustment, the synthetic
  rigs and the OpenCV exports use it; its one implementation, :func:`distort`,
  :func:`distortion_jacobian` and :func:`undistort`, is :mod:`kisscal.dlt.lens`'s (the
  DLT's L12..L16 use it too), imported here.
- Kolahi's lens terms L12..L16 (Kolahi et al. 2007), in the DLT's pixel frame.
- The grid's 30-coefficient polynomial (Küçük 2005, eq. 2.2) from raw pixels to the
  pixels the terms above act on: the grid polynomial as a lens.

``raw --polynomial--> --L12..L16--> --Brown⁻¹--> ideal``; :meth:`Camera.project` runs it
backwards from a lab point, :meth:`Camera.undistort_px` forwards from a raw pixel.
:func:`camera_linearisation` turns a Brown lens into the polynomial that the rest of
kisscal exchanges (the grid's form), and :meth:`Camera.from_dlt` reads a DLT.

References
----------
Abdel-Aziz, Y. I., & Karara, H. M. (1971). Direct linear transformation from comparator
coordinates into object space coordinates in close-range photogrammetry.
Bradski, G. (2000). The OpenCV library. Dr. Dobb's Journal of Software Tools.
Brown, D. C. (1966). Decentering distortion of lenses. Photogrammetric Engineering 32(3).
Brown, D. C. (1971). Close-range camera calibration. Photogrammetric Engineering 37(8).
Kolahi, A., Hoviattalab, M., Rezaeian, T., Alizadeh, M., Bostan, M., & Mokhtarzadeh, H.
(2007). Design of a marker-based human motion tracking system. Biomedical Signal
Processing and Control, 2, 59-67.
Küçük, C. (2005). 3D marker tracking for human gait analysis. MSc thesis, Middle East
Technical University, Ankara.
Lawson, C. L. (1961). Contributions to the theory of linear least maximum approximation
(thesis, University of California, Los Angeles).
Woltring, H. J., & Huiskes, R. (1990). Stereophotogrammetry. In Biomechanics of Human
Movement (Berme & Cappozzo, eds.).

Examples
--------
>>> import numpy as np
>>> K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])
>>> cam = Camera(K, np.eye(3), np.array([0, 0, 3000.0]), np.array([-0.1, 0, 0, 0, 0]))
>>> raw = cam.project([[300.0, 200.0, 0.0]])
>>> np.round(cam.undistort_px(raw) - cam.project_ideal([[300.0, 200.0, 0.0]]), 9) + 0.0
array([[0., 0.]])
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from kisscal._shared import in_image
from kisscal.dlt.camera import decompose_dlt
from kisscal.dlt.lens import distort, undistort
from kisscal.dlt.lens import distort_each as distort_each
from kisscal.dlt.lens import distortion_jacobian as distortion_jacobian
from kisscal.dlt.model import dlt_from_krt, project
from kisscal.dlt.nonlinear import correct_lens
from kisscal.errors import InputError
from kisscal.grid.poly import (
    Linearisation,
    apply_linearisation,
    fit_polynomial,
    invert_linearisation,
)

#: Brown lens terms, in the order of OpenCV's distortion vector (its first five).
LENS_TERMS: tuple[str, ...] = ("k1", "k2", "p1", "p2", "k3")
#: Lengths of a distortion vector OpenCV accepts.
LENS_LENGTHS: tuple[int, ...] = (4, 5, 8, 12)
_LAWSON_ROUNDS = 8


def normalised_to_px(K: ArrayLike, xn: ArrayLike) -> NDArray[np.float64]:
    """Pixels ``K (xn, yn, 1)``, one ``K`` (3, 3) for all or one per row (n, 3, 3)."""
    K, xn = np.asarray(K, dtype=float), np.asarray(xn, dtype=float)
    u = K[..., 0, 0] * xn[..., 0] + K[..., 0, 1] * xn[..., 1] + K[..., 0, 2]
    v = K[..., 1, 1] * xn[..., 1] + K[..., 1, 2]
    return np.stack([u, v], axis=-1)


def px_to_normalised(K: ArrayLike, uv: ArrayLike) -> NDArray[np.float64]:
    """Normalised coordinates of pixels (inverse of :func:`normalised_to_px`)."""
    K, uv = np.asarray(K, dtype=float), np.asarray(uv, dtype=float)
    y = (uv[..., 1] - K[..., 1, 2]) / K[..., 1, 1]
    x = (uv[..., 0] - K[..., 0, 2] - K[..., 0, 1] * y) / K[..., 0, 0]
    return np.stack([x, y], axis=-1)


def rotation_matrices(rotvec: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrices of rotation (Rodrigues) vectors, shape (n, 3, 3)."""
    return Rotation.from_rotvec(np.asarray(rotvec, dtype=float).reshape(-1, 3)).as_matrix()


def _checked(name: str, value: ArrayLike, shape: tuple[int, ...], cam: str) -> NDArray:
    a = np.array(value, dtype=float)
    if a.shape != shape or not np.all(np.isfinite(a)):
        size = " x ".join(map(str, shape))
        raise InputError(f"camera {cam or '?'}: {name} must be {size} finite numbers")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Camera:
    """One camera: pinhole ``K [R | t]`` and its lens (see the module's description).

    Attributes
    ----------
    K : ndarray, shape (3, 3)
        Intrinsic matrix (``K[2, 2] = 1``), pixels; the principal point in kisscal's (and
        OpenCV's) pixel convention, the top-left pixel's centre at (0, 0).
    R : ndarray, shape (3, 3)
        Rotation lab -> camera (rows: image right, image down, optical axis).
    t : ndarray, shape (3,)
        Translation (mm): ``x_cam = R X + t``.
    lens : ndarray, shape (4,), (5,), (8,) or (12,)
        Brown's terms on normalised coordinates, OpenCV's order (zeros: none).
    id : str
        The camera's id in ``session.toml`` (``cam1`` ...).
    size_px : (int, int) or None
        Image width and height in pixels, when known.
    linearisation : Linearisation or None
        The grid polynomial, raw px -> the pixels the DLT (with L12..L16) maps to.
    kolahi : ndarray, shape (5,), or None
        Kolahi's L12..L16, when the calibration fitted them.
    """

    K: NDArray[np.float64]
    R: NDArray[np.float64]
    t: NDArray[np.float64]
    lens: NDArray[np.float64] = field(default_factory=lambda: np.zeros(len(LENS_TERMS)))
    id: str = ""
    size_px: tuple[int, int] | None = None
    linearisation: Linearisation | None = None
    kolahi: NDArray[np.float64] | None = None
    _dlt: NDArray[np.float64] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        for name, shape in (("K", (3, 3)), ("R", (3, 3)), ("t", (3,))):
            object.__setattr__(self, name, _checked(name, getattr(self, name), shape, self.id))
        lens = np.array(self.lens, dtype=float).ravel()
        if lens.size not in LENS_LENGTHS:
            raise InputError(f"camera {self.id}: Brown lens terms must be 4, 5, 8 or 12")
        object.__setattr__(self, "lens", lens)
        if self.kolahi is not None:
            kolahi = _checked("lens terms L12..L16", self.kolahi, (5,), self.id)
            object.__setattr__(self, "kolahi", kolahi)
        if self.size_px is not None:
            object.__setattr__(self, "size_px", (int(self.size_px[0]), int(self.size_px[1])))

    @classmethod
    def from_dlt(
        cls,
        L: ArrayLike,
        id: str = "",
        linearisation: Linearisation | None = None,
        kolahi: ArrayLike | None = None,
        size_px: tuple[int, int] | None = None,
        lens: ArrayLike | None = None,
    ) -> Camera:
        """The camera of DLT parameters L1..L11 (Woltring & Huiskes 1990, eq. 15), kept as
        given; ``K``, ``R`` and ``t`` are their decomposition."""
        L = _checked("DLT parameters", L, (11,), id)
        try:
            K, R, centre = decompose_dlt(L)
        except np.linalg.LinAlgError:
            raise InputError(f"camera {id}: the DLT parameters are degenerate") from None
        lens = np.zeros(len(LENS_TERMS)) if lens is None else lens
        return cls(K, R, -R @ centre, lens, id, size_px, linearisation, kolahi, L)

    @cached_property
    def dlt(self) -> NDArray[np.float64]:
        """L1..L11 of ``K [R | t]``, shape (11,): the DLT as fitted when the camera was
        made from one (:meth:`from_dlt`), else computed from ``K``, ``R`` and ``t``."""
        if self._dlt is not None:
            return self._dlt
        return _checked("DLT parameters", dlt_from_krt(self.K, self.R, self.t), (11,), self.id)

    @property
    def centre_mm(self) -> NDArray[np.float64]:
        """Projection centre in lab mm."""
        return -self.R.T @ self.t

    @property
    def has_brown(self) -> bool:
        """Whether Brown's distortion is not the identity."""
        return bool(np.any(self.lens))

    def to_camera(self, xyz_mm: ArrayLike) -> NDArray[np.float64]:
        """Lab mm -> camera-frame mm, shape (..., 3)."""
        return np.asarray(xyz_mm, dtype=float) @ self.R.T + self.t

    def depth_mm(self, xyz_mm: ArrayLike) -> NDArray[np.float64]:
        """Distance along the optical axis (negative behind the camera)."""
        return self.to_camera(xyz_mm)[..., 2]

    def project_ideal(self, xyz_mm: ArrayLike) -> NDArray[np.float64]:
        """Lab points -> ideal (linearised) pixels through the DLT, shape (..., 2)."""
        return project(self.dlt, xyz_mm)

    def project(self, xyz_mm: ArrayLike) -> NDArray[np.float64]:
        """Lab points -> raw pixels, where the camera's image shows them, shape (..., 2)."""
        if self.has_brown:
            pc = self.to_camera(xyz_mm)
            uv = normalised_to_px(self.K, distort(self.lens, pc[..., :2] / pc[..., 2:3]))
            return self._unlinearise(uv)
        return self._unlinearise(self.project_ideal(xyz_mm))

    def undistort_px(self, uv_raw_px: ArrayLike) -> NDArray[np.float64]:
        """Raw pixels -> ideal pixels: the polynomial, L12..L16, Brown's inverse."""
        uv = np.asarray(uv_raw_px, dtype=float)
        flat = uv.reshape(-1, 2)
        if self.linearisation is not None and len(flat):
            flat = apply_linearisation(self.linearisation, flat)
        flat = correct_lens(self.dlt, self.kolahi, flat)
        if self.has_brown:
            flat = normalised_to_px(self.K, undistort(self.lens, px_to_normalised(self.K, flat)))
        return flat.reshape(uv.shape)

    def distort_px(self, uv_ideal_px: ArrayLike) -> NDArray[np.float64]:
        """Ideal pixels -> raw pixels (inverse of :meth:`undistort_px`)."""
        uv = np.asarray(uv_ideal_px, dtype=float)
        if self.has_brown:
            uv = normalised_to_px(self.K, distort(self.lens, px_to_normalised(self.K, uv)))
        return self._unlinearise(uv)

    def _unlinearise(self, uv_px: NDArray[np.float64]) -> NDArray[np.float64]:
        """Undo L12..L16 (a fixed point: the terms are small), then the polynomial."""
        shape, uv = uv_px.shape, uv_px.reshape(-1, 2)
        if self.kolahi is not None and len(uv):
            target = uv
            for _ in range(50):
                step = target - correct_lens(self.dlt, self.kolahi, uv)
                uv = uv + step
                if np.abs(step).max() < 1e-10:
                    break
        if self.linearisation is not None and len(uv):
            uv = invert_linearisation(self.linearisation, uv)
        return uv.reshape(shape)

    def in_image(self, uv_px: ArrayLike, margin_px: float = 0.0) -> NDArray[np.bool_]:
        """Whether pixels lie on the image, ``margin_px`` inside its border."""
        if self.size_px is None:
            raise InputError(f"camera {self.id}: image size unknown")
        return in_image(uv_px, self.size_px, margin_px)

    def transformed(self, rotation: ArrayLike, shift_mm: ArrayLike) -> Camera:
        """This camera after the lab frame changes by ``X' = rotation X + shift_mm``."""
        R = self.R @ np.asarray(rotation, dtype=float).T
        t = self.t - R @ np.asarray(shift_mm, dtype=float)
        return Camera(
            self.K, R, t, self.lens, self.id, self.size_px, self.linearisation, self.kolahi
        )


def camera_linearisation(
    camera: Camera,
    size_px: tuple[int, int],
    before: Linearisation | None = None,
    data_px: ArrayLike | None = None,
    minimax: bool = False,
) -> tuple[Linearisation, float]:
    """The 30-coefficient polynomial taking raw pixels to the camera's distortion-free pixels.

    A fourth-order polynomial cannot follow a lens model exactly. The least-squares fit
    is weighted where it matters, on the raw image positions the camera was calibrated
    from (``data_px``), with a 25 x 25 lattice over the whole image (corners included)
    carrying a tenth of their total weight so the polynomial stays faithful where there
    were none. With ``minimax`` (for a polynomial that is the whole lens model, without a
    grid's before it) Lawson's reweighting (Lawson 1961) then spreads the error evenly,
    which brings the image corners to about a third of the least-squares error there,
    for a little more inside.

    Parameters
    ----------
    camera : Camera
        Its lens acts on the coordinates ``before`` produces (raw pixels if None).
    size_px : (int, int)
        Image width and height.
    before : Linearisation, optional
        A linearisation applied first (a grid's), composed with the lens inverse.
    data_px : array_like, shape (n, 2), optional
        Raw positions of the observations (default: the lattice alone).
    minimax : bool
        Spread the largest errors evenly (Lawson's iteratively reweighted least squares).

    Returns
    -------
    lin : Linearisation
        Normalised on the image centre and half the larger side (as the grid stage does).
    fit_max_px : float
        Largest distance between the polynomial and the exact map over the lattice (px).
    """
    w, h = size_px
    u, v = np.meshgrid(np.linspace(-0.5, w - 0.5, 25), np.linspace(-0.5, h - 0.5, 25))
    lattice = np.column_stack([u.ravel(), v.ravel()])
    data = np.zeros((0, 2)) if data_px is None else np.asarray(data_px, dtype=float).reshape(-1, 2)
    raw = np.concatenate([lattice, data])
    share = 0.1 * len(data) / len(lattice) if len(data) else 1.0
    weights = np.r_[np.full(len(lattice), share), np.ones(len(data))]
    mid = raw if before is None else apply_linearisation(before, raw)
    target = camera.undistort_px(mid)
    centre, scale = ((w - 1) / 2.0, (h - 1) / 2.0), max(w, h) / 2.0
    for _ in range(_LAWSON_ROUNDS if minimax else 1):
        lin = fit_polynomial(raw, target, centre, scale, weights)
        err = np.linalg.norm(apply_linearisation(lin, raw) - target, axis=1)
        weights = weights * (err + 1e-12)
        weights /= weights.mean()
    return lin, float(err[: len(lattice)].max())
