"""The calibrated camera rig: one object for every stage that needs the cameras.

A :class:`Rig` holds one :class:`kisscal.camera.Camera` per camera: its id, image size,
grid linearisation (raw pixels -> linearised pixels; Küçük 2005, 2.2), DLT parameters
L1..L11 (lab mm -> linearised pixels; Abdel-Aziz & Karara 1971) and, when a calibration
fitted them, Kolahi's lens terms L12..L16 (Kolahi et al. 2007). Stages take a rig instead
of parallel dictionaries of linearisations and stacked ``(n, 11)`` arrays; the camera order
of a rig is the order of its cameras and every camera index in a long 2D table refers to it.

The rig is frozen: calibration routes build a new one, nothing changes one in place
(unlike the mutable camera groups of some tools). The rig of a processed session is
:func:`kisscal.session.current_rig` (the session layer reads files; the rig does not).

References
----------
Abdel-Aziz, Y. I., & Karara, H. M. (1971). Direct linear transformation from comparator
coordinates into object space coordinates in close-range photogrammetry.
Küçük, C. (2005). 3D marker tracking for human gait analysis. MSc thesis, Middle East
Technical University, Ankara.
Kolahi, A., Hoviattalab, M., Rezaeian, T., Alizadeh, M., Bostan, M., & Mokhtarzadeh, H.
(2007). Design of a marker-based human motion tracking system. Biomedical Signal
Processing and Control, 2, 59-67.

Examples
--------
>>> import numpy as np
>>> from kisscal.dlt.model import dlt_from_krt
>>> K = np.array([[800.0, 0, 320], [0, 800, 240], [0, 0, 1]])
>>> from kisscal.camera import Camera
>>> left = Camera.from_dlt(dlt_from_krt(K, np.eye(3), [0, 0, 3000.0]), "left")
>>> right = Camera.from_dlt(dlt_from_krt(K, np.eye(3), [-500.0, 0, 3000]), "right")
>>> rig = Rig((left, right))
>>> uv = rig.project([[100.0, 50.0, 0.0]])          # (cameras, points, 2)
>>> tri = rig.triangulate([0, 1], uv[:, 0])          # one point seen by both cameras
>>> np.round(tri.xyz_mm, 6) + 0.0
array([[100.,  50.,   0.]])
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal._shared import as_points
from kisscal.camera import Camera
from kisscal.dlt.model import project_rows
from kisscal.dlt.triangulate import Triangulation, triangulate_observations
from kisscal.errors import InputError


@dataclass(frozen=True)
class Observations:
    """A long table of 2D observations, one row per blob, sorted by field then camera.

    Attributes
    ----------
    field : ndarray of int, shape (n,)
    camera : ndarray of int, shape (n,)
        Index of the camera in its rig.
    uv_px : ndarray, shape (n, 2)
        Linearised (and lens-corrected) pixel coordinates.
    raw_px : ndarray, shape (n, 2), optional
        The same observations as measured (raw pixels), when known.
    """

    field: NDArray[np.int64]
    camera: NDArray[np.int64]
    uv_px: NDArray[np.float64]
    raw_px: NDArray[np.float64] | None = None

    def __len__(self) -> int:
        return len(self.field)


@dataclass(frozen=True)
class Rig:
    """The calibrated cameras of a session, in session order.

    Attributes
    ----------
    cameras : tuple of kisscal.camera.Camera
    """

    cameras: tuple[Camera, ...]
    _index: dict[str, int] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        cams = tuple(self.cameras)
        ids = [c.id for c in cams]
        if len(set(ids)) != len(ids):
            raise InputError(f"a rig's camera ids must be distinct, got {ids}")
        object.__setattr__(self, "cameras", cams)
        object.__setattr__(self, "_index", {c: i for i, c in enumerate(ids)})

    def __len__(self) -> int:
        return len(self.cameras)

    def __iter__(self) -> Iterator[Camera]:
        return iter(self.cameras)

    @property
    def ids(self) -> tuple[str, ...]:
        """Camera ids, in rig order."""
        return tuple(c.id for c in self.cameras)

    @property
    def dlts(self) -> NDArray[np.float64]:
        """DLT parameters of every camera, shape (n_cameras, 11)."""
        return np.stack([c.dlt for c in self.cameras]) if self.cameras else np.zeros((0, 11))

    def index(self, camera_id: str) -> int:
        """Position of a camera in the rig."""
        if camera_id not in self._index:
            raise InputError(f"no camera {camera_id!r} in the rig ({', '.join(self.ids)})")
        return self._index[camera_id]

    def camera(self, camera_id: str) -> Camera:
        """The camera with this id."""
        return self.cameras[self.index(camera_id)]

    def observations(self, blobs_px: Mapping[str, Sequence[ArrayLike]]) -> Observations:
        """The long table of a trial's 2D data, linearised.

        Parameters
        ----------
        blobs_px : mapping of camera id -> sequence of (n_f, 2) arrays
            Raw blob centroids of every field, per camera; cameras of the rig missing
            from the mapping contribute no rows.

        Returns
        -------
        Observations
            Sorted by field, then camera (a camera's blobs of a field in their order),
            with the raw coordinates beside the linearised ones.
        """
        fields, cams, raws = [], [], []
        for ci, cam in enumerate(self.cameras):
            frames = [np.asarray(xy, dtype=float).reshape(-1, 2) for xy in blobs_px.get(cam.id, ())]
            counts = [len(xy) for xy in frames]
            fields.append(np.repeat(np.arange(len(frames)), counts))
            cams.append(np.full(sum(counts), ci))
            raws.append(np.concatenate(frames) if frames else np.zeros((0, 2)))
        uvs = [cam.undistort_px(raw) for cam, raw in zip(self.cameras, raws, strict=True)]
        field_idx = np.concatenate([np.zeros(0), *fields]).astype(np.int64)
        cam_idx = np.concatenate([np.zeros(0), *cams]).astype(np.int64)
        uv = np.concatenate([np.zeros((0, 2)), *uvs])
        raw = np.concatenate([np.zeros((0, 2)), *raws])
        order = np.lexsort((cam_idx, field_idx))
        return Observations(field_idx[order], cam_idx[order], uv[order], raw[order])

    def project(self, xyz_mm: ArrayLike) -> NDArray[np.float64]:
        """Lab points in every camera, linearised px, shape (n_cameras, n_points, 2)."""
        xyz = as_points(xyz_mm, 3, "xyz_mm")
        return np.stack([c.project_ideal(xyz) for c in self.cameras])

    def project_rows(self, camera: ArrayLike, xyz_mm: ArrayLike) -> NDArray[np.float64]:
        """Point ``k`` in camera ``camera[k]`` (linearised px), shape (n, 2)."""
        return project_rows(self.dlts, camera, xyz_mm)

    def triangulate(
        self,
        camera: ArrayLike,
        uv_px: ArrayLike,
        point: ArrayLike | None = None,
        reweight_iterations: int = 2,
    ) -> Triangulation:
        """Least-squares 3D points from linearised observations (long format).

        ``point`` says which point each row belongs to (default: all rows one point).
        See :func:`kisscal.dlt.triangulate.triangulate_observations`.
        """
        camera = np.asarray(camera, dtype=np.int64)
        point = np.zeros(len(camera), np.int64) if point is None else np.asarray(point)
        return triangulate_observations(
            self.dlts, point, camera, uv_px, reweight_iterations=reweight_iterations
        )
