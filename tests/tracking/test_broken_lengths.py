"""Measured samples that break their segment's lengths are dropped (labelling/broken.py)."""

from __future__ import annotations

import numpy as np

from kisscal.tracking import TrackingParams
from kisscal.tracking.labelling import Labelling
from kisscal.tracking.labelling.broken import drop_broken_samples
from kisscal.tracking.labelling.pieces import join_gap_pieces
from kisscal.tracking.tracks import MEASURED, make_tracks
from tests.tracking.test_bodyfill import rigid_body

GAP = slice(100, 160)  # marker C hidden
PIECE = slice(110, 150)  # C seen again, as an unnamed piece
WRONG = slice(135, 146)  # D's point wrong (its blob merged with a neighbour's)


def _labelling(xyz: np.ndarray) -> Labelling:
    """Markers 0-3 named A-D; C hidden in GAP with its samples in PIECE a separate
    unnamed track; D's samples in WRONG 40 mm off, away from the body's centre."""
    n = xyz.shape[1]
    keep = np.ones((4, n), dtype=bool)
    keep[2, GAP] = False
    tr, f = np.nonzero(keep)
    pts = xyz[tr, f].copy()
    off = xyz[3, WRONG] - xyz[:3, WRONG].mean(axis=0)
    rows = (tr == 3) & (f >= WRONG.start) & (f < WRONG.stop)
    pts[rows] += 40.0 * off / np.linalg.norm(off, axis=1, keepdims=True)
    piece = np.arange(PIECE.start, PIECE.stop)
    fields, track = np.r_[f, piece], np.r_[tr, np.full(piece.size, 4)]
    pts = np.r_[pts, xyz[2, PIECE]]
    m = fields.size
    tracks = make_tracks(fields, track, pts, np.full((m, 3), np.nan), np.zeros(m), np.arange(m))
    return Labelling(tracks, ("A", "B", "C", "D", "M1"), True, (4,), (), 1.0)


def _errors(got: Labelling, xyz: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Measured fields of ``name`` and their distances (mm) to its truth."""
    t = got.tracks
    rows = (t.track == got.labels.index(name)) & (t.status == MEASURED)
    j = "ABCD".index(name)
    return t.field[rows], np.linalg.norm(t.xyz_mm[rows] - xyz[j, t.field[rows]], axis=1)


def test_samples_that_break_two_partners_lengths_are_dropped_and_no_others():
    xyz = rigid_body(seed=7, noise_mm=0.3)
    before = _labelling(xyz)
    got = drop_broken_samples(before, TrackingParams())
    assert got.labels == before.labels and got.unlabelled == before.unlabelled
    fields, err = _errors(got, xyz, "D")
    assert err.max() < 3.0  # every wrong sample gone
    assert fields.size == xyz.shape[1] - (WRONG.stop - WRONG.start)  # and only those
    for name in "ABC":
        assert np.array_equal(_errors(got, xyz, name)[0], _errors(before, xyz, name)[0])


def test_a_wrong_partner_no_longer_keeps_the_marker_s_piece_from_joining_it():
    xyz = rigid_body(seed=8, noise_mm=0.3)
    params = TrackingParams()
    labelling = _labelling(xyz)
    # D's wrong samples break C's lengths where the piece is: no join without the check
    assert "M1" in join_gap_pieces(labelling, params).labels
    got = join_gap_pieces(drop_broken_samples(labelling, params), params)
    assert "M1" not in got.labels
    fields, err = _errors(got, xyz, "C")
    assert np.isin(np.arange(PIECE.start, PIECE.stop), fields).all() and err.max() < 3.0


def test_one_partner_alone_does_not_say_which_sample_is_wrong():
    xyz = rigid_body(seed=9, noise_mm=0.3)
    labelling = _labelling(xyz)
    t = labelling.tracks
    # only A is seen with D where D is wrong: A or D may be the wrong one
    hide = np.isin(t.track, (1, 2, 4)) & (t.field >= WRONG.start) & (t.field < WRONG.stop)
    sel = t.select(~hide)
    alone = Labelling(sel, labelling.labels, True, (4,), (), 1.0)
    got = drop_broken_samples(alone, TrackingParams())
    assert got.tracks.field.size == sel.field.size
