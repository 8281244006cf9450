"""A named marker's only blob held by a point no marker's name took (a ghost: two
single-view markers' rays crossing) is freed for its fill (kisscal.tracking.rayfill.freed),
against truth."""

from __future__ import annotations

import numpy as np

from kisscal.dlt.model import camera_centre_mm, project_rows
from kisscal.tracking import FILLED_RIGID, TrackingParams, spare_blobs
from kisscal.tracking.gaps import fill_gaps_logged
from kisscal.tracking.tracks import make_tracks
from tests.tracking.test_bodyfill import rigid_body
from tests.tracking.test_raychain import GAP, _spare


def _with_ghost(xyz: np.ndarray, seed: int):
    """Marker 3 and two partners hidden over ``GAP``; camera 0 sees marker 3 there, but a
    ghost point (track 4, 60 mm deeper along that ray) used the blob: the tracks (with
    each measured sample's point row) and the blobs, those of the ghost with its rows."""
    spare = _spare(xyz, seed)
    # the marker's blob is each field's first (the noise follows it, the sort is stable)
    mine = np.searchsorted(spare.field, np.arange(GAP.start, GAP.stop))
    centre = camera_centre_mm(spare.dlts[0])
    ray = xyz[3, GAP] - centre
    ghost = xyz[3, GAP] + 60.0 * ray / np.linalg.norm(ray, axis=1, keepdims=True)
    keep = np.ones(xyz.shape[:2], dtype=bool)
    keep[1:4, GAP] = False
    tr, f = np.nonzero(keep)
    f, tr = np.r_[f, np.arange(GAP.start, GAP.stop)], np.r_[tr, np.full(ghost.shape[0], 4)]
    pos = np.concatenate([xyz[tr[: keep.sum()], f[: keep.sum()]], ghost])
    tracks = make_tracks(
        f, tr, pos, np.full(pos.shape, np.nan), np.zeros(f.size), np.arange(f.size)
    )
    point = np.full(spare.field.size, -1)
    point[mine] = keep.sum() + spare.field[mine] - GAP.start  # the ghost's rows
    assert np.allclose(
        project_rows(spare.dlts, np.zeros(mine.size, int), ghost), spare.uv_px[mine], atol=0.5
    )
    return tracks, spare, point


def test_a_blob_a_nameless_point_held_fills_the_named_marker_on_its_ray():
    xyz = rigid_body(seed=3, noise_mm=0.2)
    tracks, spare, point = _with_ghost(xyz, 3)
    params = TrackingParams()
    labels = ("A", "B", "C", "D", "M1")
    args = (spare.field, spare.camera, spare.uv_px, spare.dlts)
    held = spare_blobs(*args, point)
    out, fills = fill_gaps_logged(tracks, params, held, labels, unlabelled=(4,))
    placed = [g for g in fills if g.track == 3 and g.ray_fields and g.status == FILLED_RIGID]
    assert sum(g.n_fields for g in placed) >= 30
    rows = (out.track == 3) & np.isin(out.field, np.arange(GAP.start, GAP.stop))
    err = np.linalg.norm(out.xyz_mm[rows] - xyz[3, out.field[rows]], axis=1)
    assert np.sum(err < 3.0) >= 30
    # the same blobs held by a named track's points stay its own: nothing on the ray
    _, fills = fill_gaps_logged(tracks, params, held, labels[:4] + ("E",))
    assert not [g for g in fills if g.track == 3 and g.ray_fields]


def test_a_blob_a_point_no_track_holds_fills_the_named_marker_on_its_ray():
    """The ghost's track too short to keep (lowcost 4 seed 427: 5 fields): its points
    are in no track, and the blob they used is the marker's for its fill again."""
    xyz = rigid_body(seed=3, noise_mm=0.2)
    tracks, spare, point = _with_ghost(xyz, 3)
    held = spare_blobs(spare.field, spare.camera, spare.uv_px, spare.dlts, point)
    kept = tracks.select(tracks.track != 4)
    out, fills = fill_gaps_logged(kept, TrackingParams(), held, ("A", "B", "C", "D"))
    assert sum(g.n_fields for g in fills if g.track == 3 and g.ray_fields) >= 30
    rows = (out.track == 3) & np.isin(out.field, np.arange(GAP.start, GAP.stop))
    err = np.linalg.norm(out.xyz_mm[rows] - xyz[3, out.field[rows]], axis=1)
    assert np.sum(err < 3.0) >= 30
