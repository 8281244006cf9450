"""Every default of the reconstruction stage, in one frozen dataclass."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from kisscal.params import Params, param

STRATEGIES = ("triple", "central")


@dataclass(frozen=True)
class ReconParams(Params):
    """Parameters of 3D reconstruction (stationary filter, matching, triangulation, grouping).

    Attributes
    ----------
    strategy : str
        Matching strategy: ``"triple"`` (Küçük 2005, 3.3.5: three points pairwise consistent
        in all directions, grouped into clouds; vectorised over the whole trial, the default)
        or ``"central"`` (Shafiq et al. 2001, 4.1: base camera, priority cameras, triplet
        verification, extension; field by field, about 20x slower).
    epipolar_band_px : float
        Half-width of the band around an epipolar line (px) inside which a point "lies on"
        the line (the thesis' neighbourhood distance ``s``; Shafiq's search band).
    search_radius_px : float
        Radius (px) around the intersection of two epipolar lines (equivalently the point
        transferred from two other cameras) inside which a third point verifies a triplet,
        and around a marker's projection when it is extended to the remaining cameras.
    max_candidates : int
        Most candidates per camera kept along an epipolar line, closest first (Shafiq: 5);
        central strategy only (the triple strategy ranks all triples by residual instead).
    allow_two_camera : bool
        Also make markers of blobs seen by only two cameras, from the blobs that matching
        over three or more cameras left over, when the pair reprojects within the trial's
        residual limit and its 3D point continues a trajectory (see
        ``two_camera_continuity_mm`` and :mod:`kisscal.recon.pairs`). Needed by 2- and
        3-camera rigs; in larger rigs it adds the markers that only two cameras see.
    two_camera_alone_max_cameras : int
        Rigs of up to this many cameras accept a trajectory that only two cameras see
        throughout; larger rigs accept two-camera points only where they extend the
        trajectory of a marker that three or more cameras see in neighbouring fields. In a
        rig built for three views a pair that no third camera ever confirms is more often
        a ghost (two markers merged into one blob in both views, or two markers that each
        only one camera sees, lying on one epipolar line) than a marker. Four cameras
        around a walkway see a marker with two of them for long stretches (the other
        leg hides it from the rest): there the continuity check decides (issue 27: recall
        of markers seen by exactly two cameras 75-91 % with 3, 97-99 % with 4, ghosts at
        most 0.04 %, on the lowcost preset's truth-level scenario).
    two_camera_step_mm : float
        Largest distance (mm) a marker moves from one field to the next, where a
        two-camera point looks for the trajectory it continues (300 mm: 15 m/s at 50 Hz,
        more than a foot in swing or a thrown ball).
    two_camera_continuity_mm : float
        Largest second difference ``|p(f-1) - 2 p(f) + p(f+1)|`` (mm) of three consecutive
        positions through a two-camera point: acceleration times the field interval
        squared (20 mm: 50 m/s^2 at 50 Hz, the peak of a foot marker in swing).
    two_camera_body_mm : float
        Largest error (mm) of the rigid distances by which a two-camera pair too short to
        continue a trajectory is taken (:mod:`kisscal.recon.body`, with a marker set):
        skin moves markers of one segment by a few millimetres against each other.
    two_camera_carry_s : float
        How long (s) after a marker was lost its position is still known from a marker of
        its rigid body (:mod:`kisscal.recon.carried`), to tell a two-camera piece made of
        two lost markers' rays from a marker (:mod:`kisscal.recon.claimed`). A walking
        pelvis turns by a few degrees in a second (13 mm at an iliac spine marker after
        0.9 s, within the continuity tolerance). Issue 27, lowcost seeds 303 and 312: the
        iliac spines were lost 0.7-0.9 s before their rays crossed (0.5 s finds neither
        crossing, 1-4 s both, nothing else changed); 0 carries none.
    two_camera_coast_s : float
        How long (s) a lost marker none of whose segment stays in view is still known from
        its own velocity before it was lost (:func:`~kisscal.recon.carried.coasted`): a
        walking pelvis bobs at up to about 3 m/s^2, 15 mm off after 0.1 s. Issue 27,
        modern 3 cameras seed 332: the whole pelvis was lost, each marker then seen by one
        camera, and the iliac spines' rays crossed 11 fields (73 ms) later into a ghost
        named SACR for 65 fields; 0 coasts none.
    deblend_merged : bool
        Make two-camera points of markers whose image merged with a known point's image
        into one blob (:mod:`kisscal.recon.deblend`): the blob's centroid, minus the known
        point's share, gives the hidden marker's image. Needs ``allow_two_camera``; rigs
        of up to ``deblend_max_cameras`` cameras.
    deblend_held : bool
        Also place two markers merged into one blob that a two-camera point already
        holds with one marker's own blob, the other marker's own blob free in a third
        camera (:func:`~kisscal.recon.deblend.deblend_held`; needs ``deblend_merged`` and
        the marker set).
        Issue 27, lowcost seed 303 with ``deblend_hidden``: the largest class of its
        two-camera misses that no new ghost pays for (11 of 50, one merge), recall
        97.72 -> 98.17 %, ghosts 13 -> 12; 312 98.35 -> 98.70 %, 301 and 311 +0.1 %,
        ghosts equal; kiss 3 cameras unchanged.
    deblend_hidden : bool
        Also place two markers that the same two cameras see, merged into one blob in
        one of them, by their trajectories (:mod:`kisscal.recon.hidden`): on their own
        rays, their images' area-weighted mean the merged blob, a rigid segment of the
        marker set apart. Needs ``deblend_merged`` and the marker set (``body``). Its
        points lie within 3 mm of the truth and raise two-camera recall (issue 27: kiss
        3 cameras seed 302, 97.73 -> 98.87 %) at no ghost's or identity switch's cost.
        Pairs with no trajectory yet are placed the same way from their two pair points
        (:mod:`kisscal.recon.seeded`): kiss 3 cameras seed 305 97.72 -> 99.44 %, its
        new points within 1.8 mm, ghosts equal. Then the free pairs that continue
        those trajectories at their ends within ``hidden_prediction_mm`` of their
        predictions (:mod:`kisscal.recon.ends`): 305 99.44 -> 99.59 %, 304 99.48 ->
        99.84 %, new points within 1.4 mm.
    hidden_prediction_mm : float
        Farthest (mm) such a marker's solved position lies from its trajectory's
        constant-velocity prediction (or its pair point, :mod:`kisscal.recon.seeded`):
        a marker beside another's image (hidden from that
        camera, not merged) fits the blob only when both are pushed along their rays
        by more than a field's change of velocity. Also the SD of those predictions
        as the fit's prior, which holds the two depths where the blob and the length
        leave them free to trade.
    deblend_max_cameras : int
        Largest rig that deblends: with more cameras a marker merged in one view is
        seen by three others nearly always, and the few deblended points (placed by
        another point's projection) were as often 10 mm off as right (issue 27: kiss
        preset, 6 cameras).
    deblend_radius_px : float
        Farthest (px) a known point's projection lies from a blob it shares with another
        marker: the centroid of two overlapping images lies within one marker image's
        radius of each.
    merged_pair_rms_factor : float
        A two-camera point holding a merged blob gives way to the marker deblended with
        its clean blob only if its residual exceeds this many times the trial's median
        ``rms_px`` (a true merge pulls the pair off its epipolar lines; a blob beside the
        image of a marker hidden from its camera does not, and its residual is noise:
        lowcost seed 313, 0.07 px against a median of 0.04, deblended 14 mm off).
    merged_pull_mm : float
        A two-camera point one of whose blobs may be merged with another point's image
        is refused (:func:`~kisscal.recon.unmerged.pulled_pairs`) when the deblended pair
        fits its blobs better by more than the trial's median residual and lies farther
        than this (mm) from it: the merge pulls the point along the other camera's ray by
        that much.
    max_rms_px : float
        Largest reprojection ``rms_px`` (px) of a triple and of an accepted 3D marker;
        worse markers lose their worst observation (split) or are dropped. Generous on
        purpose (calibration error): the adaptive limit below does the fine work.
    outlier_rms_factor : float
        The residual limit of a trial is tightened to this many times the median
        ``rms_px`` of its markers (a marker far noisier than its trial holds a wrong or
        merged blob); 0 keeps ``max_rms_px`` alone.
    outlier_floor_px : float
        The tightened limit never goes below this (px), so that near-perfect data does not
        make the limit vanish.
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
    stationary_min_s : float
        Shortest trial (s) whose stationary detections are all removed: a subject holds a
        marker still for up to about 1 s within a movement trial, which must then last
        1 s / ``stationary_fraction`` for a still marker not to pass for an LED. Shorter
        trials (and trials in which nothing moves) keep their detections.
    camera_clearance_mm : float
        3D points closer than this (mm) to a camera's projection centre are dropped: they
        are LED rings (another camera's LEDs, seen by two cameras, reconstruct at that
        camera, and so does a pair of its LED with any blob of that camera), never
        markers. 0 keeps them.
    led_radius_px : float
        A blob within this distance (px) of an epipole (where another camera's centre
        projects) may be that camera's LED ring; a point made of such blobs alone is
        dropped (the lines between two pairs of cameras facing each other cross, at
        camera height, and their four LEDs agree on a point there). The ring sits around
        the lens, a few cm from the projection centre, and the calibration places the
        centre about as well. 0 keeps them.
    min_coverage : float
        A trial whose points fill less than this fraction of its fields x its marker count
        (the 90th percentile of points per field) gets a coverage warning (0..1).
    max_unmatched_fraction : float
        A trial that leaves more than this fraction of its blobs (after the stationary
        filter) unmatched gets a warning (0..1): markers seen by one camera only, blobs
        of no marker, or a calibration that does not fit.
    """

    section: ClassVar[str] = "recon"

    strategy: str = param("triple", choices=STRATEGIES)
    epipolar_band_px: float = param(3.0, unit="px", gt=0)
    search_radius_px: float = param(3.0, unit="px", gt=0)
    max_candidates: int = param(5, ge=1)
    allow_two_camera: bool = param(True)
    two_camera_alone_max_cameras: int = param(4, ge=0)
    two_camera_step_mm: float = param(300.0, unit="mm", gt=0)
    two_camera_continuity_mm: float = param(20.0, unit="mm", gt=0)
    two_camera_body_mm: float = param(10.0, unit="mm", gt=0)
    two_camera_carry_s: float = param(1.0, unit="s", ge=0)
    two_camera_coast_s: float = param(0.1, unit="s", ge=0)
    deblend_merged: bool = param(True)
    deblend_held: bool = param(True)
    deblend_hidden: bool = param(True)
    hidden_prediction_mm: float = param(10.0, unit="mm", gt=0)
    deblend_max_cameras: int = param(4, ge=0)
    deblend_radius_px: float = param(3.0, unit="px", gt=0)
    merged_pair_rms_factor: float = param(3.0, gt=0)
    merged_pull_mm: float = param(5.0, unit="mm", gt=0)
    max_rms_px: float = param(2.0, unit="px", gt=0)
    outlier_rms_factor: float = param(5.0, ge=0)
    outlier_floor_px: float = param(0.2, unit="px", gt=0)
    reweight_iterations: int = param(2, ge=0)
    group_radius_mm: float = param(10.0, unit="mm", gt=0)
    stationary_filter: bool = param(True)
    stationary_radius_px: float = param(1.5, unit="px", gt=0)
    stationary_fraction: float = param(0.5, gt=0, le=1)
    stationary_min_s: float = param(2.0, unit="s", ge=0)
    camera_clearance_mm: float = param(200.0, unit="mm", ge=0)
    led_radius_px: float = param(10.0, unit="px", ge=0)
    min_coverage: float = param(0.9, ge=0, le=1)
    max_unmatched_fraction: float = param(0.25, ge=0, le=1)


DEFAULT_PARAMS = ReconParams()
"""The defaults, shared so that functions can take ``params=DEFAULT_PARAMS``."""
