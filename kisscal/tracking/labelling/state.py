"""What labelling knows about a trial while its phases run: :class:`LabelState`.

The state holds the pieces (long ones also as a dense track x field table), the marker
set (names, template, its distances, its mirror image, the given rigid segments) and
the names given so far: ``label_of`` per piece and ``name_pos``, the trajectory each name
has gathered. Phases read it and name pieces through :meth:`LabelState.name_piece`, the
one place where names are given.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.params import TrackingParams
from kisscal.tracking.rigid import mirror_permutation
from kisscal.tracking.tracks import MEASURED, Tracks

# Two labelled tracks are taken to be on one rigid segment when their distance varies by
# less than this (SD, mm) and matches the template's within RIGID_MATCH_MM.
RIGID_SPREAD_MM = 5.0
RIGID_MATCH_MM = 15.0
#: Fields two named trajectories must share for their distance to count (as rigid, or as
#: a length): a knee and a heel seen together in a few fields of one stance keep their
#: distance by chance.
MIN_SHARED_FIELDS = 10
#: The body fit's answer is clear when the runner-up is this many times farther than
#: the best name (:func:`.spread.by_body_fit`; also :func:`.unseen.name_by_segment` and
#: :func:`.pelvis.settle_pelvis_offsets`).
CLEAR_RATIO = 1.5
#: The one name a piece's rigid partners leave needs the body fit within this many
#: ``label_tolerance_mm`` only (:func:`.spread.by_body_fit`, :func:`.unseen.name_by_segment`).
LONE_NAME_REACH = 2.0


def rich_fields(present: NDArray) -> NDArray[np.int64]:
    """Fields where at least 80 % of the largest number of simultaneous tracks are seen."""
    count = present.sum(axis=0)
    return np.flatnonzero(count >= max(3, 0.8 * count.max()))


def _pair_distances(dense: NDArray, tracks: NDArray, fields: NDArray) -> NDArray:
    pts = dense[np.ix_(tracks, fields)]  # (k, F, 3)
    return np.linalg.norm(pts[:, None] - pts[None, :], axis=3)  # (k, k, F)


def median_distances(dense: NDArray, tracks: NDArray, fields: NDArray) -> NDArray:
    """Median over ``fields`` of the distance between every pair of ``tracks`` (NaN-aware)."""
    return np.nanmedian(_pair_distances(dense, tracks, fields), axis=2)


def distance_spread(dense: NDArray, tracks: NDArray, fields: NDArray, shared: bool = False):
    """Standard deviation over ``fields`` of the distance between every pair of tracks
    and, with ``shared``, the number of ``fields`` that hold both of a pair."""
    d = _pair_distances(dense, tracks, fields)
    return (np.nanstd(d, axis=2), np.isfinite(d).sum(axis=2)) if shared else np.nanstd(d, axis=2)


def segment_mask(names: tuple[str, ...], segments: list | tuple | None) -> NDArray[np.bool_]:
    """The session's rigid ``segments`` as a symmetric name x name mask."""
    n = len(names)
    rigid = np.zeros((n, n), dtype=bool)
    index = {name: i for i, name in enumerate(names)}
    for pair in segments or ():
        if len(pair) == 2 and pair[0] in index and pair[1] in index:
            rigid[index[pair[0]], index[pair[1]]] = rigid[index[pair[1]], index[pair[0]]] = True
    return rigid


@dataclass(eq=False)
class LabelState:
    """The pieces of one trial, the marker set, and the names given so far.

    Attributes
    ----------
    tracks : Tracks
        Every piece, short ones included.
    names, template, segments, params
        The marker set (names, (n, 3) standing template in any frame, rigid pairs) and
        the tracking parameters.
    template_distance : (n, n) array
        Distances between template markers (mm).
    mirror_of : (n,) int array or None
        Each name's left/right mirror name (None when the set has no mirror symmetry).
    given_rigid : (n, n) bool array or None
        The session's segments as a mask (None without segments).
    n_measured : (n_tracks,) int array
        Measured samples per piece.
    long_ids : (L,) int array
        Pieces of at least ``min_track_length`` measured samples.
    dense, present : (L, n_fields, 3) and (L, n_fields) arrays
        The long pieces' positions (NaN where not seen) and where they are seen.
    start, stop : (n_tracks,) int arrays
        Row range of each piece in ``tracks``.
    window : int
        Fields of a matching window.
    label_of : (n_tracks,) int array
        Name index per piece, -1 while unnamed.
    name_pos : (n, n_fields, 3) array
        Where each name has been seen so far (NaN elsewhere).
    rich : int array
        Fields of the first matched window (rigid pairs are judged on them).
    fit_rms : float
        Median rigid-fit RMS (mm) of the first window's names to the template.
    upright : bool
        Template and lab share the vertical (Z up), as a shipped set's template does:
        matches that turn the body over are refused.
    partial : bool
        The trial may hold only part of the set, and markers of other sets: a window's
        pieces and names are first narrowed to those the upright match finds near each
        other (:func:`~kisscal.tracking.labelling.window.set_members`; needs ``upright``).
    doubtful : set of int
        Names a phase gave while another way of giving them fitted nearly as well (a
        foot among foreign markers, :func:`~kisscal.tracking.labelling.feet.settle_feet`):
        flagged in the result.
    """

    tracks: Tracks
    names: tuple[str, ...]
    template: NDArray[np.float64]
    segments: tuple
    params: TrackingParams
    template_distance: NDArray[np.float64]
    mirror_of: NDArray[np.int64] | None
    given_rigid: NDArray[np.bool_] | None
    n_measured: NDArray[np.int64]
    long_ids: NDArray[np.int64]
    dense: NDArray[np.float64]
    present: NDArray[np.bool_]
    start: NDArray[np.int64]
    stop: NDArray[np.int64]
    window: int
    label_of: NDArray[np.int64]
    name_pos: NDArray[np.float64]
    rich: NDArray[np.int64] = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    fit_rms: float = float("nan")
    upright: bool = False
    partial: bool = False
    doubtful: set[int] = field(default_factory=set)

    @classmethod
    def begin(
        cls,
        tracks: Tracks,
        names: tuple[str, ...],
        template: NDArray,
        segments: list | tuple | None,
        params: TrackingParams,
    ) -> LabelState | None:
        """The state before any name is given; None with fewer than three long pieces."""
        n_measured = tracks.n_status(MEASURED)
        # Long tracks get a dense (track, field) table; the many short pieces (mostly
        # ghosts) are read from their own rows only.
        long_ids = np.flatnonzero(n_measured >= params.min_track_length)
        if long_ids.size < 3:
            return None
        n_fields = int(tracks.field.max()) + 1
        rows = np.isin(tracks.track, long_ids)
        dense = np.full((long_ids.size, n_fields, 3), np.nan)
        where = np.searchsorted(long_ids, tracks.track[rows])
        dense[where, tracks.field[rows]] = tracks.xyz_mm[rows]
        start, stop = tracks.bounds()
        return cls(
            tracks=tracks,
            names=names,
            template=template,
            segments=tuple(segments or ()),
            params=params,
            template_distance=np.linalg.norm(template[:, None] - template[None, :], axis=2),
            mirror_of=mirror_permutation(template, params.label_tolerance_mm),
            given_rigid=segment_mask(names, segments) if segments else None,
            n_measured=n_measured,
            long_ids=long_ids,
            dense=dense,
            present=np.isfinite(dense[..., 0]),
            start=start,
            stop=stop,
            window=min(params.label_window_fields, n_fields),
            label_of=np.full(tracks.n_tracks, -1, dtype=np.int64),
            name_pos=np.full((len(names), n_fields, 3), np.nan),
        )

    @property
    def n_fields(self) -> int:
        return self.name_pos.shape[1]

    def piece(self, t: int) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Fields and positions of piece ``t``."""
        rows = slice(self.start[t], self.stop[t])
        return self.tracks.field[rows], self.tracks.xyz_mm[rows]

    def name_piece(self, t: int, j: int) -> None:
        """Give piece ``t`` name ``j``: its samples join that name's trajectory."""
        self.label_of[t] = j
        fields, xyz = self.piece(t)
        self.name_pos[j, fields] = xyz

    def rigid_pairs(self) -> NDArray[np.bool_]:
        """Name pairs on one rigid segment: the given segments, plus named trajectories
        whose distance barely varies over :attr:`rich` and equals the template's, seen
        together in :data:`MIN_SHARED_FIELDS` of those fields (or all of them, when
        fewer), and, in a set with a mirror image, whose mirror pair is found so too."""
        n = len(self.names)
        seen = np.isfinite(self.name_pos[:, self.rich, 0]).astype(float)
        shared = seen @ seen.T
        judged = shared >= min(MIN_SHARED_FIELDS, self.rich.size)
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # pairs never seen together
            spread = distance_spread(self.name_pos, np.arange(n), self.rich)
            median = median_distances(self.name_pos, np.arange(n), self.rich)
            ok = (
                (spread < RIGID_SPREAD_MM)
                & (np.abs(median - self.template_distance) < RIGID_MATCH_MM)
                & judged
            )
            if self.mirror_of is not None:
                # A segment's mirror image is a segment: a pair across a joint keeps its
                # length while that joint pauses (a hip in one stance), while the other
                # leg's, in swing then, varies.
                m = self.mirror_of
                ok &= (judged & (spread < RIGID_SPREAD_MM))[np.ix_(m, m)]
        np.fill_diagonal(ok, False)
        return segment_mask(self.names, self.segments) | ok
