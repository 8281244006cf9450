"""An unnamed piece past a named trajectory's end with no partner measured beside it
joins it by its path alone (kisscal.tracking.labelling.pieces), against truth."""

from __future__ import annotations

import numpy as np

from kisscal.tracking import TrackingParams
from kisscal.tracking.labelling import Labelling
from kisscal.tracking.labelling.pieces import join_gap_pieces
from kisscal.tracking.tracks import make_tracks
from tests.tracking.test_bodyfill import rigid_body

END, PIECE = 150, 160  # the body measured to END, one marker seen again from PIECE


def _past_end(xyz: np.ndarray, names: str, marker: int) -> Labelling:
    """The markers named in ``names`` (of "ABCD") measured up to :data:`END`, and
    ``marker`` seen again from :data:`PIECE` as an unnamed piece, no other marker there
    (kiss 3 cameras seed 418: the right heel seen by two cameras at the walk's end, ankle
    and toe by one)."""
    keep = ["ABCD".index(n) for n in names]
    n = xyz.shape[1]
    f = np.r_[np.tile(np.arange(END), len(keep)), np.arange(PIECE, n)]
    t = np.r_[np.repeat(np.arange(len(keep)), END), np.full(n - PIECE, len(keep))]
    pts = np.r_[xyz[keep, :END].reshape(-1, 3), xyz[marker, PIECE:]]
    m = f.size
    tracks = make_tracks(f, t, pts, np.full((m, 3), np.nan), np.zeros(m), np.arange(m))
    return Labelling(tracks, (*names, "M1"), True, (len(keep),), (), 1.0)


def test_a_piece_continuing_a_trajectory_s_path_takes_its_name_without_lengths():
    xyz = rigid_body(seed=9, noise_mm=0.3)
    got = join_gap_pieces(_past_end(xyz, "ABCD", 3), TrackingParams())
    assert got.unlabelled == ()
    rows = got.tracks.track == got.labels.index("D")
    assert np.isin(np.arange(PIECE, xyz.shape[1]), got.tracks.field[rows]).all()
    err = np.linalg.norm(got.tracks.xyz_mm[rows] - xyz[3, got.tracks.field[rows]], axis=1)
    assert err.max() < 2.0


def test_a_piece_of_a_marker_never_named_does_not_take_a_neighbour_s_name():
    # C (90 mm from D, 80 from A) never named: its piece starts a step from D's and A's
    # paths wider than a quarter of their distance to their nearest marker (70 mm)
    xyz = rigid_body(seed=9, noise_mm=0.3)
    got = join_gap_pieces(_past_end(xyz, "ABD", 2), TrackingParams())
    assert got.labels == ("A", "B", "D", "M1") and got.unlabelled == (3,)
