"""The tracks alive while :func:`~kisscal.tracking.tracker.track_points` walks the fields.

Tracking a trial costs one step per field, 10 000 for 200 s at 50 Hz, and on a few dozen
tracks a numpy call costs its overhead (about a microsecond) whatever its size: the step
is written for few calls (issue 18's profile), and gives the same numbers as the thesis'
per-track filters:

- every row is computed whether alive or not: one call on all rows costs the same as on
  the live ones, and it spares gathers and scatters;
- a filter's covariance depends only on its age (every field predicts and corrects), so
  its gain is looked up (:func:`~kisscal.tracking.predictors.kalman_gains`); likewise the
  coasting drift by misses and Shafiq's weights by points;
- when no point is wanted by two gates and no gate holds two points, the gating is the
  assignment: the linear sum assignment runs only on conflicts;
- samples are kept per field as gathered rows and made one table at the end.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

import kisscal.tracking.association as assoc
import kisscal.tracking.cluster as cluster
from kisscal.tracking.association import ambiguous_rows, associate, gate_costs, lookahead_cost
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.predictors import extrapolation_weights, kalman_gains, shafiq_rule
from kisscal.tracking.tracks import MEASURED, PREDICTED, Tracks, make_tracks

_HISTORY = 5
_SINGLE_STEP_WEIGHT = 0.1
# Weight of the newest squared error in each predictor's running error (per track).
_ERROR_MEMORY = 0.5
# A track's point nearer its prediction than this (mm) is not judged against its rivals
# (:meth:`Live._close_rivals`): a few times the noise of reconstructed points.
RIVAL_MIN_MM = 10.0
# A one-point track's first step longer than this many times the fastest filtered track's
# speed is cut (:meth:`Live._fast_first_steps`).
_FIRST_STEP_FACTOR = 1.5


@dataclass(frozen=True)
class Setup:
    """What every field's step needs from the parameters, computed once.

    Tables indexed by a row's counters, each at most the number of steps plus one:
    ``shafiq`` and ``floor`` by its number of points, ``gain`` by its filter's age and
    ``drift`` by its consecutive misses.
    """

    params: TrackingParams
    m_axes: NDArray
    k_axes: NDArray
    w_pos: NDArray
    w_vel: NDArray
    shafiq: NDArray
    floor: NDArray
    gain: NDArray
    drift: NDArray
    depth: int = _HISTORY

    @classmethod
    def of(cls, params: TrackingParams, n_steps: int) -> Setup:
        n_init = params.min_initial_length
        w_pos = extrapolation_weights(n_init, 1, 0)
        shafiq = np.zeros((_HISTORY + 1, _HISTORY))
        for n in range(1, _HISTORY + 1):
            used, degree = shafiq_rule(n)
            shafiq[n, _HISTORY - used :] = extrapolation_weights(used, degree, 1)
        counts = np.arange(n_steps + 2)
        # An initial track's gate is at least half the initial gate, a one-point track's
        # the whole (its extrapolation is the point itself, so the other term is 0).
        floor = np.full((n_steps + 2, 1), 0.5 * params.initial_gate_mm)
        floor[1] = params.initial_gate_mm
        return cls(
            params=params,
            m_axes=np.asarray(params.gate_m),
            k_axes=np.asarray(params.gate_k_mm_per_field),
            w_pos=w_pos,
            w_vel=extrapolation_weights(n_init, 1, 1) - w_pos,
            shafiq=shafiq[np.minimum(counts, _HISTORY)],
            floor=floor,
            gain=kalman_gains(params.initial_error, params.pnc, params.mnc, n_steps + 1),
            drift=(0.5 * params.coast_accel_mm_per_field2 * ((counts + 1) ** 2 - 1))[:, None],
            # an initial track's first filter state is fitted to its last n_init points
            depth=max(_HISTORY, n_init),
        )


def _cut_pieces(field: NDArray, track: NDArray, cuts: list[tuple[int, NDArray]]) -> NDArray:
    """Piece numbers after cutting each track before its sample at each cut field."""
    span = int(field.max()) + 1
    cut_keys = np.concatenate([t * span + f for f, t in cuts])
    key = track * span + field
    order = np.argsort(key, kind="stable")
    starts = np.isin(key[order], cut_keys)
    starts[1:] |= track[order][1:] != track[order][:-1]
    starts[0] = True
    piece = np.empty_like(track)
    piece[order] = np.cumsum(starts) - 1
    return piece


class Samples:
    """The samples tracking emits, gathered field by field; :meth:`tracks` makes the table."""

    def __init__(self) -> None:
        self._fields: list[int] = []
        self._parts: list[tuple[NDArray, ...]] = []
        self._cuts: list[tuple[int, NDArray]] = []

    def cut(self, field: int, track: NDArray) -> None:
        """Start a new piece of each track of ``track`` at ``field`` (an ambiguous
        assignment: blending judges the join from both sides)."""
        if track.size:
            self._cuts.append((field, track))

    def add(
        self, field: int, track: NDArray, point: NDArray, xyz: NDArray, filtered: NDArray
    ) -> None:
        """One sample per entry of ``track``: ``point`` is the input row (-1: coasted,
        the prediction stands in), ``filtered`` (k, 3, 2) the filter state (position,
        velocity per axis), NaN for a track without a filter."""
        self._fields.append(field)
        self._parts.append((track, point, xyz, filtered))

    def tracks(self) -> Tracks:
        track, point, xyz, filtered = (np.concatenate(c) for c in zip(*self._parts, strict=True))
        sizes = [p[0].size for p in self._parts]
        field = np.repeat(np.asarray(self._fields, dtype=np.int64), sizes)
        if self._cuts:
            track = _cut_pieces(field, track, self._cuts)
        return make_tracks(
            field,
            track,
            xyz,
            filtered[:, :, 0],
            np.where(point >= 0, MEASURED, PREDICTED),
            point,
        )


class Live:
    """Struct of arrays for the tracks alive at the current field, with spare rows.

    ``state`` holds each filter's (position, velocity) per axis; an initial track (no
    filter yet) has NaN there, which marks its samples as unfiltered. Dead rows are
    computed too, and never recorded.
    """

    def __init__(self, setup: Setup, capacity: int = 16) -> None:
        self.setup = setup
        self.samples = Samples()
        self.ids = np.full(capacity, -1, dtype=np.int64)
        # Points, filter age and consecutive misses, counted up together each field.
        self.counts = np.zeros((capacity, 3), dtype=np.int64)
        self.history = np.zeros((capacity, setup.depth, 3))
        self.state = np.zeros((capacity, 3, 2))
        self.kalman = np.zeros(capacity, dtype=bool)
        self.alive = np.zeros(capacity, dtype=bool)
        # Running squared errors of the filter's and the constant-acceleration prediction.
        self.errors = np.zeros((capacity, 2))
        # Tracks whose point was ambiguous: cut where they next take one.
        self.pending = np.zeros(capacity, dtype=bool)
        self.ambiguous = np.zeros(capacity, dtype=bool)
        self._candidates = (np.zeros((capacity, 3)), np.zeros((capacity, 3)))
        # Speed (mm/field) of the fastest filtered track this field (None: no such track).
        self._speed: float | None = None
        self._bind()

    def _bind(self) -> None:
        """Views of the counters, and scratch space, for the current capacity."""
        self.n, self.age, self.misses = self.counts.T
        self._sample_point = np.empty(self.alive.size, dtype=np.int64)  # scratch of _update

    def add(self, field: int, ids: NDArray, point: NDArray, xyz: NDArray) -> None:
        """Start a track on each point (lowest free rows first) and record its sample."""
        slots = np.flatnonzero(~self.alive)
        if slots.size < ids.size:
            self._grow(ids.size - slots.size)
            slots = np.flatnonzero(~self.alive)
        slots = slots[: ids.size]
        self.ids[slots] = ids
        self.counts[slots] = (1, 0, 0)
        self.history[slots] = 0.0
        self.history[slots, -1] = xyz
        self.state[slots] = np.nan  # no filter yet
        self.kalman[slots] = False
        self.alive[slots] = True
        self.errors[slots] = 0.0
        self.pending[slots] = False
        self.samples.add(field, ids, point, xyz, self.state[slots])

    def _grow(self, extra: int) -> None:
        more = max(extra, self.ids.size)
        names = ("ids", "counts", "history", "state", "kalman", "alive", "errors")
        for name in (*names, "pending", "ambiguous"):
            old = getattr(self, name)
            pad = np.full((more, *old.shape[1:]), -1 if name == "ids" else 0, dtype=old.dtype)
            setattr(self, name, np.concatenate([old, pad]))
        self._bind()

    def step(self, field: int, point: NDArray, points: NDArray, later: NDArray) -> list[int]:
        """Extend the live tracks by this field's ``points`` (input rows ``point``), with
        ``later`` the next field's points; returns which points were taken."""
        self._speed = None
        pred, half = self._predict()
        rows, cols = self._gate(pred, half, points, later)
        args = (self.history, self.n, self.alive & (self.misses == 0), points, rows, cols)
        radius = self.setup.params.cluster_radius_mm
        if cluster.carry(pred, *args, radius, RIVAL_MIN_MM):
            self.ambiguous.fill(False)  # assigned again from the carried predictions
            rows, cols = self._gate(pred, half, points, later)
        if self.setup.params.rival_ratio > 0 and rows.size:
            self._close_rivals(pred, points, rows, cols)
        if self._speed is not None and rows.size:
            self._fast_first_steps(pred, points, rows, cols)
        seen = (self.n[rows] >= 3) & (self.misses[rows] == 0)
        if seen.any() and later.shape[0]:  # a doubt on the nearest: the field after judges
            args = (self.history[rows[seen], -3:], points[cols[seen]], points, later, RIVAL_MIN_MM)
            self.ambiguous[rows[seen][assoc.continuation_doubts(*args)]] = True
        if (ratio := self.setup.params.certain_ratio) > 0 and rows.size:
            kal, found = rows[self.kalman[rows]], points[cols[self.kalman[rows]]]
            spread = np.sqrt(np.maximum(self.errors[kal].min(axis=1), self.setup.params.mnc))
            lost = self.alive & (self.misses == 0) & (np.bincount(rows, minlength=len(pred)) == 0)
            args = (pred[kal], found, points, spread, ratio, pred[self.alive], pred[lost])
            self.ambiguous[kal[assoc.certain_rows(*args)]] = False
        args = (self.history, self.n, self.alive & (self.misses == 0), points, rows, cols)
        self.ambiguous[cluster.broken(*args, radius, RIVAL_MIN_MM)] = True  # blending judges
        self._update(field, pred, rows, cols, points, point)
        return cols.tolist()

    def _predict(self) -> tuple[NDArray, NDArray]:
        """Predicted position and gate half-widths (T, 3) of every row."""
        setup, params = self.setup, self.setup.params
        state, kal = self.state, self.kalman[:, None]
        # Kalman prediction (thesis eq. 3.14): x' = x + v; v' = v.
        state[..., 0] += state[..., 1]
        position = state[..., 0]
        last = self.history[:, -_HISTORY:]  # Shafiq's rule uses up to five points
        parabola = np.einsum("tk,tkc->tc", setup.shafiq[self.n], last)
        # A fast limb accelerates and decelerates within a few fields, and the filter's
        # constant velocity lags it by more than markers on it are apart: a track whose
        # constant-acceleration prediction (the quadratic through its last three points)
        # has lately done better is predicted by it (a choice between two motion models
        # by their recent errors, after Blom & Bar-Shalom 1988's interacting models).
        quadratic = 3.0 * (last[:, -1] - last[:, -2]) + last[:, -3]
        self._candidates = (position.copy(), quadratic)
        accelerating = (self.n >= 3) & (self.errors[:, 1] < self.errors[:, 0])
        pred = np.where(kal, np.where(accelerating[:, None], quadratic, position), parabola)
        # Gate of a filtered track: eq. 3.16, widened while coasting.
        half_kalman = setup.m_axes * np.maximum(np.abs(state[..., 1]), setup.k_axes)
        half_kalman += setup.drift[self.misses]
        if params.lag_widening:
            # A filter with little process noise lags an accelerating marker; the distance
            # from its prediction to Shafiq's five-point parabola through the track's last
            # positions measures that lag, and widens the gate.
            half_kalman += np.abs(parabola - position)
        if params.gate_error_factor:
            half_kalman += self._error_widening(state[..., 1])
        step = np.abs(parabola - self.history[:, -1])
        half_initial = np.maximum(params.initial_gate_factor * step, self._young_floor())
        return pred, np.where(kal, half_kalman, half_initial)

    def _young_floor(self) -> NDArray:
        """Least gate half-width (T, 1) or (T, 3) of each initial track: the initial gate
        for a one-point track, half of it for a two-point one (a velocity of one step); from
        three points on, the Kalman gate (eq. 3.16) of the fastest filtered track's speed
        when smaller (a marker appearing 53 mm from where another vanished at 2 mm/field,
        BTS.c3d, is not taken in). Keeps that speed for :meth:`_fast_first_steps`."""
        setup = self.setup
        floor = setup.floor[self.n]
        seen = self.alive & self.kalman
        if not seen.any():
            return floor
        velocity = self.state[seen, :, 1]
        speed = np.sqrt(np.einsum("tc,tc->t", velocity, velocity).max())
        self._speed = float(speed)
        young = np.minimum(floor, setup.m_axes * np.maximum(speed, setup.k_axes))
        return np.where(self.n[:, None] >= 3, young, floor)

    def _error_widening(self, velocity: NDArray) -> NDArray:
        """How much each row's gate widens (T, 1) for its recent prediction errors
        (``gate_error_factor``), at most its filter's speed so that a slow noisy marker's
        gate does not grow over its neighbours (NaN for rows without a filter)."""
        rms = np.sqrt(self.errors.min(axis=1))
        speed = np.sqrt(np.einsum("tc,tc->t", velocity, velocity))
        return np.minimum(self.setup.params.gate_error_factor * rms, speed)[:, None]

    def _gate(
        self, pred: NDArray, half: NDArray, points: NDArray, later: NDArray
    ) -> tuple[NDArray, NDArray]:
        """Matched rows and points: each point in at most one gate, one per gate."""
        # Axis by axis on contiguous (T, M) planes: several times faster than reducing a
        # (T, M, 3) array over its short last axis. |d| <= h is exactly |d / h| <= 1 in
        # IEEE arithmetic (the division rounds above 1 whenever |d| > h), the gate test
        # of :func:`~kisscal.tracking.association.associate`.
        pred_t, half_t = np.ascontiguousarray(pred.T), np.ascontiguousarray(half.T)
        near = np.abs(np.ascontiguousarray(points.T)[:, None, :] - pred_t[:, :, None])
        near = near <= half_t[:, :, None]
        inside = near[0] & near[1]
        inside &= near[2]
        inside &= self.alive[:, None]
        rows, cols = inside.nonzero()
        if assoc.one_to_one(rows, cols):
            # No point is wanted by two gates and no gate holds two points: the
            # assignment is the gating itself.
            return rows, cols
        return self._assign(inside, pred, half, points, later)

    def _assign(
        self, inside: NDArray, pred: NDArray, half: NDArray, points: NDArray, later: NDArray
    ) -> tuple[NDArray, NDArray]:
        """One-to-one assignment where gates conflict: Kalman tracks choose first; initial
        tracks take from what is left, those with a velocity before those of one point."""
        params = self.setup.params
        kal = self.kalman
        single = ~kal & (self.n == 1)
        rows_alive = self.alive.nonzero()[0]
        taken = np.zeros(points.shape[0], dtype=bool)
        out_rows, out_cols = [np.empty(0, dtype=np.int64)], [np.empty(0, dtype=np.int64)]
        for tier in (kal, ~kal & ~single, single):
            rows = rows_alive[tier[rows_alive]]
            free = (~taken).nonzero()[0]
            if rows.size == 0 or free.size == 0:
                continue
            r, c = inside[rows][:, free].nonzero()
            if not assoc.one_to_one(r, c):
                # Only rows and points in some gate can pair: the costs are for those.
                rr, cc = np.unique(r), np.unique(c)
                sub_rows, sub_pts = rows[rr], points[free[cc]]
                extra, weight = None, 1.0
                if tier is single:
                    # A one-point track has no velocity: how far the candidate lies says
                    # little (a fast foot moves more than a slow marker's neighbour is
                    # away); whether the pair continues says much.
                    extra = lookahead_cost(
                        pred[sub_rows], sub_pts, later, 0.5 * params.initial_gate_mm
                    )
                    weight = _SINGLE_STEP_WEIGHT
                elif tier is kal:
                    # Markers of one fast limb share their prediction error, and a track
                    # whose own point is missing can take a neighbour's: whether the track
                    # goes on through the candidate into the next field tells them apart
                    # (weighed lightly: a slow marker's neighbour continues almost as well).
                    extra = lookahead_cost(
                        self.history[sub_rows, -1], sub_pts, later, 2.0 * params.initial_gate_mm
                    )
                r, c = associate(pred[sub_rows], half[sub_rows], sub_pts, extra, weight)
                if params.ambiguity_margin > 0:
                    judged = self._judge(
                        tier is single, pred[sub_rows], half[sub_rows], sub_pts, r, c, extra
                    )
                    self.ambiguous[sub_rows[judged]] = True
                r, c = rr[r], cc[c]
            out_rows.append(rows[r])
            out_cols.append(free[c])
            taken[free[c]] = True
        rows, cols = np.concatenate(out_rows), np.concatenate(out_cols)
        if params.ambiguity_margin > 0:
            self._nearer_losers(inside, pred, points, rows, cols)
        return rows, cols

    def _close_rivals(self, pred: NDArray, points: NDArray, rows: NDArray, cols: NDArray) -> None:
        """Mark ambiguous a track of two points or more (a one-point track's first step says
        little) that ``rival_ratio`` says may have taken a neighbour's point."""
        d_own = np.linalg.norm(points[cols] - pred[rows], axis=1)
        far = (d_own > RIVAL_MIN_MM) & (self.n[rows] >= 2)
        if not far.any() or points.shape[0] < 2:
            return
        rows, cols, d_own = rows[far], cols[far], d_own[far]
        d = np.linalg.norm(points[None, :, :] - pred[rows][:, None, :], axis=2)
        d[np.arange(rows.size), cols] = np.inf
        close = d.min(axis=1) < self.setup.params.rival_ratio * d_own
        self.ambiguous[rows[close]] = True

    def _fast_first_steps(
        self, pred: NDArray, points: NDArray, rows: NDArray, cols: NDArray
    ) -> None:
        """Mark ambiguous a one-point track whose first step is more than
        :data:`_FIRST_STEP_FACTOR` times the speed of the fastest filtered track (at least
        the gate's ``k``): a marker that vanishes a field after it appeared leaves its
        one-point track the nearest other marker in the wide initial gate (the basket
        sprint of the C3D regression set: 45 mm while every marker moves 2 mm per field)."""
        one = self.n[rows] == 1
        if not one.any():
            return
        rows, cols = rows[one], cols[one]
        step = np.linalg.norm(points[cols] - pred[rows], axis=1)
        limit = _FIRST_STEP_FACTOR * max(self._speed, float(self.setup.k_axes.max()))
        self.ambiguous[rows[step > limit]] = True

    def _judge(
        self,
        single: bool,
        pred: NDArray,
        half: NDArray,
        points: NDArray,
        r: NDArray,
        c: NDArray,
        extra: NDArray | None,
    ) -> NDArray[np.bool_]:
        """Which of a tier's rows in conflict chose ambiguously: for tracks with a
        velocity, another one-to-one choice nearly as cheap (:func:`ambiguous_rows`, with
        the look-ahead ``extra`` cost they chose by); for one-point tracks, whose choice
        weighs the field after more than the distance, a choice other than the nearest
        one-to-one."""
        params = self.setup.params
        if single:
            near_r, near_c = associate(pred, half, points)
            nearest = np.full(pred.shape[0], -1)
            nearest[near_r] = near_c
            chosen = np.full(pred.shape[0], -1)
            chosen[r] = c
            return nearest != chosen
        inside, cost = gate_costs(pred, half, points, extra)
        return ambiguous_rows(cost, inside, r, c, params.ambiguity_margin)

    def _nearer_losers(
        self, inside: NDArray, pred: NDArray, points: NDArray, rows: NDArray, cols: NDArray
    ) -> None:
        """Mark ambiguous the takers and losers of points a track left without one
        contests (:func:`~kisscal.tracking.association.contested_points`)."""
        losers = self.alive.copy()
        losers[rows] = False
        if not losers.any() or rows.size == 0:
            return
        lost = losers.nonzero()[0]
        fresh = (self.misses[lost] == 0) & (self.n[lost] >= 2)
        args = (inside[np.ix_(lost, cols)], pred[rows], pred[lost], points[cols], fresh)
        nearer = assoc.contested_points(*args, self.setup.params.rival_ratio, RIVAL_MIN_MM)
        self.ambiguous[rows[nearer.any(axis=0)]] = True
        self.ambiguous[lost[nearer.any(axis=1)]] = True

    def _score_predictors(self, rows: NDArray, found: NDArray) -> None:
        """Update the running squared error of both predictions of the rows that found a
        point (a track without a filter yet scores the filter as the other)."""
        own, other = (np.sum((c[rows] - found) ** 2, axis=1) for c in self._candidates)
        own = np.where(np.isnan(own), other, own)
        new = np.stack([own, other], axis=1)
        self.errors[rows] += _ERROR_MEMORY * (new - self.errors[rows])

    def _update(
        self,
        field: int,
        pred: NDArray,
        rows: NDArray,
        cols: NDArray,
        points: NDArray,
        point: NDArray,
    ) -> None:
        """Correct the filters with the points found (or the predictions, §3.3.9), start
        filters on initial tracks long enough, record the samples, end the tracks lost."""
        setup, params = self.setup, self.setup.params
        hit = np.zeros(self.alive.size, dtype=bool)
        hit[rows] = True
        self._score_predictors(rows, points[cols])
        # A missing point is replaced by the prediction, as if measured (§3.3.9).
        z = pred
        z[rows] = points[cols]
        state = self.state
        innovation = z - state[..., 0]
        state += setup.gain[self.age][:, None, :] * innovation[:, :, None]
        # An initial track ends at its first miss, a filtered one after max_coasted_fields.
        stay = hit | (self.kalman & (self.misses < params.max_coasted_fields))
        self.counts += 1
        self.misses[rows] = 0
        self.history[:, :-1] = self.history[:, 1:]
        self.history[:, -1] = z
        # Only an initial track reaches n_init now (a filtered one had it before).
        born = hit & (self.n == params.min_initial_length)
        if born.any():
            recent = self.history[born, -params.min_initial_length :]
            state[born, :, 0] = np.einsum("k,tkc->tc", setup.w_pos, recent)
            state[born, :, 1] = np.einsum("k,tkc->tc", setup.w_vel, recent)
            self.age[born] = 0
            self.kalman[born] = True
        # An ambiguous track, or one that was and took no point then, starts a new piece
        # with the point it takes.
        if self.pending.any() or self.ambiguous.any():
            cut = hit & (self.pending | self.ambiguous)
            self.samples.cut(field, self.ids[cut])
            self.pending = (self.pending | self.ambiguous) & ~hit & stay
            self.ambiguous.fill(False)
        out = (self.alive & stay).nonzero()[0]
        sample_point = self._sample_point
        sample_point.fill(-1)
        sample_point[rows] = point[cols]
        self.samples.add(field, self.ids[out], sample_point[out], z[out], state[out])
        self.alive &= stay
