"""Every default of the tracking stage, in one frozen dataclass.

Units: positions in lab millimetres, time in fields (one field = one image, ``1 / rate_hz``
seconds), so velocities are in mm/field. The Kalman noise covariances follow the thesis
(Küçük 2005, §3.3.9 and chapter 5) as it set them in OpenCV: ``Q = pnc * I`` (2 x 2, on
(mm, mm/field)), ``R = mnc`` (mm²), ``P0 = initial_error * I``, one filter per lab axis.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from kisscal.params import Params, param

#: Fewest fields a distance between two markers must be measured in before its mean and SD
#: are trusted (a length partner, a rigid cluster, a broken-piece test), however small
#: ``body_context_fields`` is set: with fewer, one noisy sample sets the SD.
MIN_LENGTH_FIELDS = 4


@dataclass(frozen=True)
class TrackingParams(Params):
    """Parameters of tracking, blending, gap filling, labelling and smoothing.

    Attributes
    ----------
    pnc : float
        Process noise covariance of each per-axis constant-velocity Kalman filter
        (``Q = pnc * I``; mm² and (mm/field)²). The thesis swept 0.005, 0.05, 0.5.
    mnc : float
        Measurement noise covariance (``R = mnc``, mm²). The thesis swept 0.1, 0.05, 0.025.
    initial_error : float
        Initial a-posteriori error covariance (``P0 = initial_error * I``).
    gate_m : tuple of float
        Gate factor ``m`` per axis (x, y, z) of the thesis' gate f(v) = m*|v| for |v| >= k,
        else m*k (eq. 3.16); dimensionless. The gate is a box of half-width f(v) per axis.
    gate_k_mm_per_field : tuple of float
        Velocity threshold ``k`` per axis (mm/field) below which the gate keeps its
        minimum half-width ``m*k``.
    coast_accel_mm_per_field2 : float
        Largest acceleration per axis (mm/field²) the gate allows for while a track coasts:
        after n missed fields the gate grows by a (n+1)²/2 - a/2, the drift of a constant-
        velocity prediction from a marker accelerating at a (5 mm/field² = 12.5 m/s² at 50 Hz).
    lag_widening : bool
        Widen each Kalman gate per axis by the distance between the filter's prediction and
        Shafiq's five-point parabola through the track's last positions, so that filters
        with little process noise (which lag accelerating markers) keep their tracks.
    gate_error_factor : float
        Widen each Kalman gate per axis by this many times the RMS of the track's own recent
        prediction errors (the running error of the prediction in use), at most by the
        track's step per field: a fast limb's acceleration changes within a few fields, and
        markers on it can be closer than its prediction misses them by (a serve at 50 Hz,
        a push-rim stroke at 70 Hz). 0 turns it off.
    ambiguity_margin : float
        Where gates conflict, a Kalman track whose point another one-to-one choice explains
        almost as well (a swap with another track, a point it lost or left, costing less than
        this much more in gate-normalised squared distance) is cut there into two pieces,
        and blending, which sees both sides, joins them: fast close markers are otherwise
        exchanged by a one-sided prediction. 0 turns it off.
    certain_ratio : float
        A Kalman track is never cut as ambiguous (``ambiguity_margin``, ``rival_ratio``)
        when every other point of the field lies more than this many times farther than
        the larger of its point and its own recent RMS prediction error
        (:func:`~kisscal.tracking.association.certain_rows`): the gate grows with speed, a
        smooth marker's misses do not (LEDs on a golf club 5 mm apart at 3 m/s). 0: off.
    rival_ratio : float
        A track of two points or more (coasting too) whose point lies more than 10 mm from
        its prediction is cut there likewise when another point of the field, in its gate
        or not, lies less than this many times as far: a track whose marker vanished
        takes the nearest neighbour, which its prediction misses by about as much (C3D
        regression set: a glove at 70 Hz, hands at 120 Hz). 0 turns it off.
    first_step_ratio : float
        The first step of a piece that never became a Kalman track (one point: no
        velocity, its prediction is the point itself) is split off as a guess when it is
        longer than 10 mm and another point of that field lies less than this many times
        as far from the first point: the step is the marker's whole motion, not a miss,
        and a marker of a fast limb at a low rate moves about as far as its neighbours
        are apart (PhaseSpace at 30 Hz: LEDs 30 mm apart moving 40-60 mm a field, the
        neighbour's point taken at 0.55 of the distance to the marker's own); likewise,
        at any length, when another point of the first field lies less than this many
        times as far from the second point and its track ended there (that track, left
        with no point, could have taken it: Phoenix LEDs 3-8 mm apart on a golf club).
        What is left of a split piece is judged again, at most ``min_initial_length``
        passes: its next step was taken with the velocity the guess gave. 0 turns it off.
    cluster_radius_mm : float
        Radius (mm) of the rigid cluster (LEDs a few centimetres apart on a hand) whose
        common move predicts a track its own prediction cannot tell from its neighbours
        (:func:`~kisscal.tracking.cluster.carry`; PhaseSpace's hand at 30 Hz, LEDs
        30-70 mm apart moving 60-170 mm a field), and within which a track whose new point
        changes its distance to such a neighbour is cut (:func:`~kisscal.tracking.cluster.broken`).
        0 turns both off.
    initial_gate_mm : float
        Search radius (mm) around a track's only point when it has one point (thesis §3.3.8:
        the start point is its own prediction).
    initial_gate_factor : float
        While a track is still an initial track (fewer than ``min_initial_length`` points),
        its gate is this many times the extrapolated step length, at least ``initial_gate_mm``
        / 2 (the thesis' constant neighbouring distance grown with speed).
    min_initial_length : int
        Points an initial track needs before its three Kalman filters are initialised on it.
    max_coasted_fields : int
        Consecutive fields without a point in the gate after which a Kalman track ends (the
        predicted position stands in for the missing point meanwhile).
    min_reacquired_fields : int
        After coasting, a track must find points in this many consecutive fields for them
        to stay on it; shorter runs (typically ghosts caught by a coasting gate after the
        marker left the view) are split off as pieces of their own, for blending to decide.
    split_tolerance_mm : float
        A track is cut where a cubic through three measured samples on each side fits them
        worse than this RMS (mm): the path jumped to another marker.
    split_noise_factor : float
        The split tolerance is at least this many times the trial's own smoothness
        residual (median cubic-fit residual of 6-sample windows, about the noise).
    blend_gap_fields : int
        Largest number of missing fields between the end of one track piece and the start of
        another for automatic blending (Shafiq et al. 2001 §4.3 use two fields; the
        continuity check guards longer gaps, which ghost run splits and flickering
        visibility at the edge of the volume create).
    blend_reach_mm : float
        Coarse gate of blending: Shafiq's extrapolations from both pieces across the gap
        must land within this distance (mm) per field crossed of the other piece.
    blend_points : int
        Measured points taken from each side of a gap for the continuity fit.
    blend_tolerance_mm : float
        Largest RMS residual (mm) of the cubic through both sides of a gap for the two
        pieces to be blended (about 4 x the residual of a true join at 0.5 mm noise).
    blend_noise_factor : float
        The blend tolerance is at least this many times the trial's smoothness residual.
    blend_join_points : int
        Measured samples a side through which one cubic judges a join as smooth as its
        pieces (three a side fit a fast marker's neighbour: a basket sprint at 120 Hz,
        2.6 mm across a 3-field gap; five, against each piece's own path, do not).
    blend_piece_points : int
        Measured samples at a piece's end whose own cubic residual is the piece's roughness.
    blend_rougher : float
        A join may be at most this many times rougher than its pieces (C3D regression set:
        a wrong join 8 times, a fast glove's true joins within 3.1 times).
    blend_rival_share : float
        A sample of another piece in a join's gap this near one side's extrapolation, as a
        share of the distance between the two sides' extrapolations there, is that side's
        marker seen in the gap and the join is refused (C3D regression set: the two wrong
        joins have their rival at 0.01 and 0.11 of it; the nearest sample of another
        marker to a right join is at 0.21).
    min_track_length : int
        Pieces with fewer measured points that take no name (or all pieces, when no marker
        set fits) are removed in the clean-up (short ghost tracks, Shafiq et al. §4.3);
        longer ones that take no name are kept and reported.
    keep_short_pieces : bool
        Keep the short pieces that take no name too (as unnamed trajectories) instead of
        removing them as ghosts: for points another system reconstructed (a C3D trial),
        where every sample is a marker's and a file may hold only a few frames.
    max_fill_gap_fields : int
        Largest gap (fields) inside one labelled trajectory that gap filling bridges.
    fill_context_fields : int
        Measured samples on each side of a gap that the filling spline is fitted to.
    max_body_fill_fields : int
        Largest gap (fields) filled from the body (rigid-body or pattern fill) when it is
        longer than ``max_fill_gap_fields`` (2 s at 150 Hz).
    body_context_fields : int
        Measured fields on each side of a gap that rigid-body and pattern fill learn the
        marker's place from (and, halved, the margin around the stretches their expected
        error is measured on).
    rigid_fill_sd_mm : float
        Largest SD (mm) of a marker's distance to the hidden one, over the fields beside
        the gap, for it to count as a marker of the hidden one's segment; rigid-body fill
        needs two of them.
    rigid_fill_neighbour_sd_mm : float
        Largest such SD (mm) for a marker to help carry the hidden one at all (a neighbour
        across a joint, weighing less the more its distance varies).
    rigid_fill_markers : int
        Markers (at most; three at least) that carry a hidden one in rigid-body fill.
    max_body_fill_error_mm : float
        Largest expected error (mm) of a rigid-body or pattern fill, measured on the
        marker's own samples beside the gap, for the gap to be filled that way.
    ray_fill_gate : float
        Single-camera fill: how many expected errors of the body's fill (converted to
        pixels at the marker) an unused blob may lie from the fill's projection for the
        filled sample to be moved onto the blob's ray.
    ray_fill_px : float
        Single-camera fill: the SD (px) of a blob's position that weighs its ray against
        the body's fill.
    ray_chain_gate_px : float
        Single-camera fill from the blob itself (:mod:`kisscal.tracking.raychain`): how far
        (px, plus half the blob's motion per field) a blob may lie from where its path in
        the image was predicted.
    ray_chain_coast_fields : int
        Fields without a blob the path in the image is continued over.
    ray_length_sd_floor_mm : float
        Smallest SD (mm) taken for a length of the marker's segment (its SD in the trial
        when larger).
    ray_length_max_error_mm : float
        Largest expected error (mm) along the ray of a field placed on it by the
        segment's lengths.
    trusted_max_error_mm : float
        Largest expected error (mm) of a hip fill made in the trusted pass, once every
        other fill is made (:func:`~kisscal.tracking.fill_hip.trusted_hip`): where the
        knee too is on a camera's ray, the solution's covariance says 5.0-5.5 mm along the
        thigh's ray (modern 3 seed 409 RTHI 166-186, 0.5-2.1 mm off), over
        ``ray_length_max_error_mm``.
    ray_depth_max_error_mm : float
        Largest expected error (mm) of a marker's distance from the one camera that sees
        it, bridged by a spline across the gap, for its blob's ray to place it
        (:mod:`kisscal.tracking.fill_depth`).
    ray_merge_px : float
        Farthest (px) another marker's projection lies from a blob it shares with the
        marker (the centroid of two overlapping images lies within one image's radius of
        each): at a track's end, the rays of two or more cameras meet on the blob with
        that marker's share taken out, when they meet better so.
    ray_rest_max_error_mm : float
        Largest expected error (mm) of a body fill between fields placed on rays (it
        borrows them as its context, and an error measured beside them tells less).
    mirror_length_sd_mm : float
        Smallest SD (mm) of a length of a marker no track took, taken from its mirror
        image's on the other side (:mod:`kisscal.tracking.fill_absent`): the sides'
        markers are placed by hand.
    refill_predicted : bool
        Replace the Kalman predictions of coasted fields inside a trajectory by the
        two-sided gap fill (status ``filled``); the count of predictions per track is kept
        in the statistics. False keeps them as ``predicted``.
    label_tolerance_mm : float
        Outlier distance (mm) of the rigid template matching, and the largest distance of a
        piece from where the body's rigid fit expects a name for it to take that name.
    label_segment_tolerance_mm : float
        Largest RMS difference (mm) between a piece's distances to the rigid partners of a
        name and the template's for the piece to take that name; in the foot contest, two
        names whose distances both fit within it are told apart by the walk alone.
    min_label_points : int
        Measured points a piece needs to be considered for a name at all.
    min_body_fit_points : int
        Measured points a piece needs to be named from the body's rigid fit alone, when no
        rigid partner of any free name is in view (more than a ghost usually lives).
    label_window_fields : int
        Length (fields) of the stretch of the trial, the one where most long tracks are
        seen together, whose average pose is matched to the template.
    label_fields : int
        Number of fields of the window sampled for template matching.
    set_window_s : float
        Labelling from a shipped marker set's generic template (no ``template_mm``): the
        first average pose is taken over a window of this many seconds, about one stride,
        so that most markers are seen whole in it.
    min_side_confidence : float
        A name whose trajectory agrees with the anatomy (left of its right partner, above
        the markers below it) in fewer than this fraction of the fields is flagged as
        uncertain; a left/right pair the wrong way round in more than this fraction is
        exchanged.
    name_deficit_fraction : float
        A name (labelling from a marker set) that another name of the set fits better
        by more than this fraction of stature (median misfit of the distances to its
        neighbours and of its height, against the set's template:
        :mod:`~kisscal.tracking.labelling.runnerup`) is flagged as uncertain.
    free_deficit_fraction : float
        ... and a name that a name no trajectory holds fits better by more than this
        fraction of stature (:func:`~kisscal.tracking.labelling.runnerup.name_margins`).
        On the regression set (issue 26) names forced one marker along the body lose to a
        free name by 0.4-2.3 % (a thigh marker named finger, the thigh's name free), true
        names by up to 2.0 % (shoulders and elbows, the free names their arm's): the two
        overlap, and at 1 % about as many true names are flagged as wrong ones caught.
    facing_fraction : float
        Toe names ahead of heel names (anterior pelvis ahead of posterior) along the walk in
        at least this fraction of the votes face forward; in at most 1 - it, turned round.
    foot_margin : float
        The foot contest (:mod:`~kisscal.tracking.labelling.feet`) gives a foot's names
        another way only when that assignment's score (mean squared relative error of its
        distances to the shank's and within the foot against the template, times
        ``1 / foot_margin`` when its toe trails its heel along the walk) is at most this
        share of the labelling's own.
    foot_reach : float
        Unnamed pieces whose median distance to a shank marker exceeds this many times the
        template's farthest foot-to-shank distance take no part in the foot contest.
    foot_candidates : int
        At most this many unnamed pieces near the shank (the most often seen) take part.
    min_label_fraction : float
        Fraction of the marker names that must be matched for a trial to fit the marker set;
        below it the tracks are named M1, M2, ...
    smoothing : bool
        Smooth final trajectories with a generalised cross-validation spline (Woltring 1986;
        ``scipy.interpolate.make_smoothing_spline``). Off by default.
    """

    section: ClassVar[str] = "tracking"

    pnc: float = param(0.5, gt=0)
    mnc: float = param(0.025, unit="mm²", gt=0)
    initial_error: float = param(1.0, gt=0)
    gate_m: tuple[float, float, float] = param((0.6, 0.6, 0.6), gt=0)
    gate_k_mm_per_field: tuple[float, float, float] = param(
        (25.0, 25.0, 25.0), unit="mm/field", gt=0
    )
    coast_accel_mm_per_field2: float = param(5.0, unit="mm/field²", ge=0)
    lag_widening: bool = param(True)
    gate_error_factor: float = param(2.0, ge=0)
    ambiguity_margin: float = param(0.5, ge=0)
    rival_ratio: float = param(1.35, ge=0)
    first_step_ratio: float = param(2.0, ge=0)
    certain_ratio: float = param(4.0, ge=0)
    cluster_radius_mm: float = param(100.0, unit="mm", ge=0)
    initial_gate_mm: float = param(120.0, unit="mm", gt=0)
    initial_gate_factor: float = param(0.6, gt=0)
    min_initial_length: int = param(5, ge=2)
    max_coasted_fields: int = param(3, unit="fields", ge=0)
    min_reacquired_fields: int = param(5, unit="fields", ge=0)
    split_tolerance_mm: float = param(5.0, unit="mm", ge=0)
    split_noise_factor: float = param(8.0, ge=0)
    blend_gap_fields: int = param(4, unit="fields", ge=0)
    blend_reach_mm: float = param(40.0, unit="mm", gt=0)
    blend_points: int = param(3, ge=0)
    blend_tolerance_mm: float = param(3.0, unit="mm", gt=0)
    blend_noise_factor: float = param(5.0, ge=0)
    blend_join_points: int = param(5, ge=2)
    blend_piece_points: int = param(10, ge=2)
    blend_rougher: float = param(4.0, gt=0)
    blend_rival_share: float = param(0.2, ge=0)
    min_track_length: int = param(10, ge=0)
    keep_short_pieces: bool = param(False)
    max_fill_gap_fields: int = param(5, unit="fields", ge=0)
    fill_context_fields: int = param(6, unit="fields", ge=0)
    max_body_fill_fields: int = param(300, unit="fields", ge=0)
    body_context_fields: int = param(20, unit="fields", ge=0)
    rigid_fill_sd_mm: float = param(3.0, unit="mm", gt=0)
    rigid_fill_neighbour_sd_mm: float = param(20.0, unit="mm", gt=0)
    rigid_fill_markers: int = param(4, ge=3)
    max_body_fill_error_mm: float = param(5.0, unit="mm", gt=0)
    ray_fill_gate: float = param(3.0, gt=0)
    ray_fill_px: float = param(0.1, unit="px", gt=0)
    ray_chain_gate_px: float = param(3.0, unit="px", gt=0)
    ray_chain_coast_fields: int = param(3, unit="fields", ge=0)
    ray_length_sd_floor_mm: float = param(1.0, unit="mm", gt=0)
    ray_length_max_error_mm: float = param(5.0, unit="mm", gt=0)
    trusted_max_error_mm: float = param(6.0, unit="mm", gt=0)
    ray_depth_max_error_mm: float = param(3.0, unit="mm", gt=0)
    ray_merge_px: float = param(3.0, unit="px", gt=0)
    ray_rest_max_error_mm: float = param(3.0, unit="mm", gt=0)
    mirror_length_sd_mm: float = param(2.0, unit="mm", gt=0)
    refill_predicted: bool = param(True)
    label_tolerance_mm: float = param(120.0, unit="mm", gt=0)
    label_segment_tolerance_mm: float = param(6.0, unit="mm", ge=0)
    min_label_points: int = param(1, ge=0)
    min_body_fit_points: int = param(5, ge=0)
    label_window_fields: int = param(500, unit="fields", ge=1)
    label_fields: int = param(40, ge=0)
    min_label_fraction: float = param(0.5, ge=0, le=1)
    facing_fraction: float = param(2 / 3, gt=0.5, le=1)
    foot_margin: float = param(0.25, gt=0, le=1)
    foot_reach: float = param(1.5, gt=0)
    foot_candidates: int = param(4, ge=0)
    set_window_s: float = param(1.0, unit="s", gt=0)
    min_side_confidence: float = param(0.8, gt=0.5, le=1)
    name_deficit_fraction: float = param(0.04, ge=0)
    free_deficit_fraction: float = param(0.01, ge=0)
    smoothing: bool = param(False)

    @property
    def length_fields(self) -> int:
        """Fields two markers must share before the SD of their distance is trusted:
        ``body_context_fields``, at least :data:`MIN_LENGTH_FIELDS`."""
        return max(self.body_context_fields, MIN_LENGTH_FIELDS)


def reconstructed_points(params: TrackingParams) -> TrackingParams:
    """``params`` for points another system reconstructed (a ``[[trials]] c3d``): no
    ghosts among them, so short pieces are kept (``keep_short_pieces``)."""
    return params.replace(keep_short_pieces=True)
