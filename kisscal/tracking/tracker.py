"""Forward tracking of 3D points field by field (Küçük 2005 §3.3.8-3.3.9).

Each new point starts an *initial track* extended by Shafiq's extrapolators; after
``min_initial_length`` points three constant-velocity Kalman filters (one per axis) take
over, with a box gate (eq. 3.16) and the prediction standing in for a missing point for up
to ``max_coasted_fields`` (:mod:`kisscal.tracking.live` steps the fields). Association is
one-to-one (:mod:`kisscal.tracking.association`); where another choice explains a field
almost as well, the tracks are cut there rather than guessed: blending sees both sides.

The pieces are then checked, because a gate can take the wrong point: a short run of
points after coasting is split off (a ghost caught after the marker left), and a track is
cut where its path is not smooth or where its first or last point strays from the rest.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from kisscal.errors import InputError
from kisscal.tracking.continuity import smoothness_mm, split_discontinuities, split_stray_ends
from kisscal.tracking.live import RIVAL_MIN_MM, Live, Setup
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import MEASURED, PREDICTED, Tracks, make_tracks


def _check_points(field: ArrayLike, xyz_mm: ArrayLike) -> tuple[NDArray, NDArray]:
    field = np.asarray(field)
    xyz = np.asarray(xyz_mm, dtype=float)
    if field.ndim != 1 or xyz.shape != (field.size, 3):
        raise InputError(
            f"tracking: need field (N,) and xyz_mm (N, 3), got {field.shape} and {xyz.shape}"
        )
    if field.size and (
        not np.issubdtype(field.dtype, np.integer) and not np.all(field == np.round(field))
    ):
        raise InputError("tracking: field indices must be whole numbers")
    if field.size and field.min() < 0:
        raise InputError("tracking: field indices must be >= 0")
    if not np.isfinite(xyz).all():
        raise InputError("tracking: xyz_mm contains NaN or infinite values")
    return field.astype(np.int64), xyz


def track_points(field: ArrayLike, xyz_mm: ArrayLike, params: TrackingParams) -> Tracks:
    """Form track pieces from 3D points per field (Küçük 2005 §3.3.8-3.3.9).

    Parameters
    ----------
    field : (N,) int array
        Field index of each 3D point (any order).
    xyz_mm : (N, 3) float array
        Lab coordinates of the points (mm).
    params : TrackingParams
        Kalman noise, gate and coasting parameters.

    Returns
    -------
    Tracks
        Every piece, including short ghost pieces (see :func:`clean_up`), with samples
        ``measured`` or ``predicted`` (coasted fields followed by a measurement).

    References
    ----------
    Küçük 2005 (Kalman tracking, gate eq. 3.16, coasting); Shafiq et al. 2001 (the
    extrapolators of initial tracks).
    """
    field, xyz = _check_points(field, xyz_mm)
    if field.size == 0:
        e = np.empty(0)
        return make_tracks(e, e, np.empty((0, 3)), np.empty((0, 3)), e, e)
    order = np.argsort(field, kind="stable")
    sorted_field, sorted_xyz = field[order], xyz[order]
    first, last = int(sorted_field[0]), int(sorted_field[-1])
    n_span = last - first + 1
    # Plain ints: indexing a list in the loop is cheaper than a numpy scalar.
    starts = np.searchsorted(sorted_field, np.arange(first, last + 2)).tolist()
    live = Live(Setup.of(params, n_span))
    next_id = 0
    for k in range(n_span):
        f, lo, hi = first + k, starts[k], starts[k + 1]
        points, point = sorted_xyz[lo:hi], order[lo:hi]
        taken: list[int] = []
        if live.alive.any():
            later = sorted_xyz[hi : starts[min(k + 2, n_span)]]
            taken = live.step(f, point, points, later)
        if len(taken) < hi - lo:
            new = np.ones(hi - lo, dtype=bool)
            new[taken] = False
            ids = np.arange(next_id, next_id + hi - lo - len(taken))
            next_id += ids.size
            live.add(f, ids, point[new], points[new])
    tracks = split_short_reacquisitions(
        trim_predicted_ends(live.samples.tracks()), params.min_reacquired_fields
    )
    tolerance = max(params.split_tolerance_mm, params.split_noise_factor * smoothness_mm(tracks))
    # One-sided extrapolation is twice as uncertain as the two-sided fit.
    tracks = split_stray_ends(split_discontinuities(tracks, tolerance), 2.0 * tolerance)
    return split_ambiguous_first_steps(trim_predicted_ends(tracks), params)


def split_ambiguous_first_steps(tracks: Tracks, params: TrackingParams) -> Tracks:
    """Split off the first point of a piece that never became a Kalman track (fewer than
    ``min_initial_length`` measured points) when its first step was a guess: longer than
    :data:`~kisscal.tracking.live.RIVAL_MIN_MM` while another point of that field lies
    less than ``first_step_ratio`` times as far from the first point, or (at any length)
    while another point of the first field lies less than ``first_step_ratio`` times as
    far from the second point and its piece ended there: that track, left with no point,
    could as well have taken it.

    One point gives no direction: the nearest candidate is taken, and on a fast limb two
    markers can be almost equally far (a serve at 50 Hz: elbow and upper arm 121 and 129
    mm from the elbow's last point). A rival track is judged at any step length: Phoenix
    LEDs 3-8 mm apart on a golf club move 10 mm a field, and when one is hidden its track
    takes the neighbour's point, 7.4 mm away against the neighbour's own 9.7 mm (a 10 mm
    floor on the step would keep that guess). Kalman tracks keep their start, as live tracking
    built them; a short piece loses nothing that blending would use.

    What is left is judged again, until no short piece starts with a guess: the step
    after a guessed one was taken with the velocity the guess gave. On PhaseSpace at 30
    Hz, where LED 8 is hidden in field 157, its track took LED 9's point there and LED
    9's young track the point of LED 10, found again: after one pass both pieces still
    held two LEDs; passes until none is split leave none (2526 -> 2638 pieces).
    """
    for _ in range(params.min_initial_length):
        split = _split_first_steps_once(tracks, params)
        if split.n_tracks == tracks.n_tracks:
            break
        tracks = split
    return tracks


def _split_first_steps_once(tracks: Tracks, params: TrackingParams) -> Tracks:
    """One pass of :func:`split_ambiguous_first_steps`."""
    meas = np.flatnonzero(tracks.status == MEASURED)
    if params.first_step_ratio <= 0 or meas.size < 3:
        return tracks
    tr = tracks.track[meas]
    lo = np.searchsorted(tr, np.arange(tracks.n_tracks), "left")
    hi = np.searchsorted(tr, np.arange(tracks.n_tracks), "right")
    short = np.flatnonzero((hi - lo >= 2) & (hi - lo < params.min_initial_length))
    first, second = meas[lo[short]], meas[lo[short] + 1]
    step = np.linalg.norm(tracks.xyz_mm[second] - tracks.xyz_mm[first], axis=1)
    # Points of one field only: each field is far from every other in a 4th coordinate.
    apart = 1e3 * (np.ptp(tracks.xyz_mm[meas]) + 1.0)
    tree = cKDTree(np.c_[apart * tracks.field[meas], tracks.xyz_mm[meas]])
    probe = np.c_[apart * tracks.field[second], tracks.xyz_mm[first]]
    reach = params.first_step_ratio * step
    within = np.asarray(tree.query_ball_point(probe, reach, return_length=True))
    # A rival track: a piece that ended in the first field (it found no point after)
    # with its last point as near the second point.
    last = meas[hi[hi > lo] - 1]
    ended = cKDTree(np.c_[apart * tracks.field[last], tracks.xyz_mm[last]])
    probe = np.c_[apart * tracks.field[first], tracks.xyz_mm[second]]
    rivals = np.asarray(ended.query_ball_point(probe, reach, return_length=True))
    # The second point itself is within reach of the first; a rival makes two.
    guess = ((step > RIVAL_MIN_MM) & (within >= 2)) | (rivals >= 1)
    if not guess.any():
        return tracks
    piece = tracks.track.copy()
    piece[first[guess]] = tracks.n_tracks + np.arange(int(guess.sum()))
    return tracks.with_track(piece)


def split_short_reacquisitions(tracks: Tracks, min_run: int) -> Tracks:
    """Split off runs of fewer than ``min_run`` measured fields that follow a coasted field.

    A coasting gate that catches a ghost after the marker has gone (out of view, or hidden
    for long) would otherwise extend the track with wrong points, while a real marker found
    again keeps being found. Such a run becomes a piece of its own: blending reconnects it
    if it continues the track, the clean-up removes it if not.
    """
    for _ in range(8):
        if tracks.field.size == 0 or min_run <= 1:
            return tracks
        meas = tracks.status == MEASURED
        same = np.r_[False, tracks.track[1:] == tracks.track[:-1]]
        consecutive = same & np.r_[False, np.diff(tracks.field) == 1]
        run_start = meas & ~(consecutive & np.r_[False, meas[:-1]])
        run_id = np.cumsum(run_start) - 1
        run_len = np.bincount(run_id[meas], minlength=int(run_start.sum()))
        after_coast = run_start & same & np.r_[False, tracks.status[:-1] == PREDICTED]
        short_runs = np.zeros(run_len.size, dtype=bool)
        short_runs[run_id[after_coast]] = run_len[run_id[after_coast]] < min_run
        split = meas & short_runs[np.maximum(run_id, 0)]
        if not split.any():
            return tracks
        # New piece numbers for the split runs, beyond every existing number.
        new_track = np.where(split, tracks.n_tracks + run_id, tracks.track)
        # Predictions between the track and the split run now end the track: drop them.
        tracks = trim_predicted_ends(tracks.with_track(new_track))
    return tracks


def trim_predicted_ends(tracks: Tracks) -> Tracks:
    """Drop predicted samples after a track's last measured sample (coasting that never
    found the marker again)."""
    if tracks.field.size == 0:
        return tracks
    last = np.full(tracks.n_tracks, -1, dtype=np.int64)
    m = tracks.status == MEASURED
    np.maximum.at(last, tracks.track[m], tracks.field[m])
    return tracks.select(tracks.field <= last[tracks.track])
