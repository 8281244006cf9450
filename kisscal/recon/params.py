"""Every default of the reconstruction stage, in one frozen dataclass."""

from __future__ import annotations

from dataclasses import dataclass

from kisscal.errors import KisscalError

STRATEGIES = ("triple", "central")


@dataclass(frozen=True)
class ReconParams:
    """Parameters of 3D reconstruction (stationary filter, matching, triangulation, grouping).

    Attributes
    ----------
    strategy : str
        Matching strategy: ``"triple"`` (Küçük 2005, 3.3.5: three points pairwise consistent
        in all directions, grouped into clouds) or ``"central"`` (Shafiq et al. 2001, 4.1:
        base camera, priority cameras, triplet verification, extension).
    epipolar_band_px : float
        Half-width of the band around an epipolar line (px) inside which a point "lies on"
        the line (the thesis' neighbourhood distance ``s``; Shafiq's search band).
    search_radius_px : float
        Radius (px) around the intersection of two epipolar lines (equivalently the point
        transferred from two other cameras) inside which a third point verifies a triplet,
        and around a marker's projection when it is extended to the remaining cameras.
    max_candidates : int
        Most candidates per camera kept along an epipolar line, closest first (Shafiq: 5).
    allow_two_camera : bool
        Accept markers seen by only two cameras (mutually closest epipolar pairs). Off by
        default: two-camera matches are the main source of ghost markers.
    max_rms_px : float
        Largest reprojection ``rms_px`` of an accepted 3D marker (px); worse markers lose
        their worst observation (split) or are dropped.
    reweight_iterations : int
        Iteratively reweighted least-squares steps after the linear DLT solution
        (Woltring & Huiskes 1990, sec. 3); 0 keeps the plain eq. 10 solution.
    group_radius_mm : float
        3D points of one field closer than this (mm) whose observations do not conflict are
        one marker (the thesis' 3D point groups, 3.3.7), re-triangulated together.
    stationary_filter : bool
        Remove stationary false detections (Küçük 2005, 3.3.1) before matching.
    stationary_radius_px : float
        Neighbourhood (px) within which detections count as "the same place" (a square
        window of half-side ``ceil(stationary_radius_px)`` pixels).
    stationary_fraction : float
        A detection is stationary if blobs sit within ``stationary_radius_px`` of it in more
        than this fraction of the trial's fields (0..1).
    """

    strategy: str = "triple"
    epipolar_band_px: float = 1.5
    search_radius_px: float = 2.0
    max_candidates: int = 5
    allow_two_camera: bool = False
    max_rms_px: float = 1.0
    reweight_iterations: int = 2
    group_radius_mm: float = 10.0
    stationary_filter: bool = True
    stationary_radius_px: float = 1.5
    stationary_fraction: float = 0.5

    def __post_init__(self) -> None:
        if self.strategy not in STRATEGIES:
            raise KisscalError(
                f"recon strategy must be one of {', '.join(STRATEGIES)}, got {self.strategy!r}"
            )
        for name in (
            "epipolar_band_px",
            "search_radius_px",
            "max_rms_px",
            "group_radius_mm",
            "stationary_radius_px",
        ):
            if not getattr(self, name) > 0:
                raise KisscalError(f"recon {name} must be > 0, got {getattr(self, name)}")
        if self.max_candidates < 1:
            raise KisscalError(f"recon max_candidates must be >= 1, got {self.max_candidates}")
        if self.reweight_iterations < 0:
            raise KisscalError(
                f"recon reweight_iterations must be >= 0, got {self.reweight_iterations}"
            )
        if not 0 < self.stationary_fraction <= 1:
            raise KisscalError(
                f"recon stationary_fraction must be in (0, 1], got {self.stationary_fraction}"
            )


DEFAULT_PARAMS = ReconParams()
"""The defaults, shared so that functions can take ``params=DEFAULT_PARAMS``."""
