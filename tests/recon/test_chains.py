"""Two-camera ghost runs: the blobs of a run that two markers' rays make, followed in
their images, come from two different points; a marker's blobs continue together."""

from __future__ import annotations

import numpy as np

from kisscal.dlt.model import project
from kisscal.recon import ReconParams
from kisscal.recon.chains import drop_split_runs

from .rig import make_rig

N_FIELDS = 12


def _table(ghost_from: int) -> tuple:
    """Two markers 400 mm apart walking together at 25 mm per field, seen by two cameras;
    from field ``ghost_from`` on, each by one camera only, and those two blobs made into
    one (ghost) point per field, as a pair matching fooled by their smooth motion would."""
    dlts = make_rig(0, n_cameras=2)
    t = np.arange(N_FIELDS)[:, None]
    xyz = {
        "A": np.column_stack([25.0 * t[:, 0], np.zeros(N_FIELDS), np.full(N_FIELDS, 900.0)]),
        "B": np.column_stack([25.0 * t[:, 0], np.full(N_FIELDS, 400.0), np.full(N_FIELDS, 900.0)]),
    }
    field, camera, uv, marker, truth = [], [], [], [], []
    next_id = 0
    for f in range(N_FIELDS):
        if f < ghost_from:
            for k, name in enumerate("AB"):
                for c in range(2):
                    field.append(f), camera.append(c), marker.append(next_id + k), truth.append(k)
                    uv.append(project(dlts[c], xyz[name][f][None])[0])
            next_id += 2
        else:
            for c, name in enumerate("AB"):  # A by camera 0, B by camera 1: one point
                field.append(f), camera.append(c), marker.append(next_id), truth.append(-1)
                uv.append(project(dlts[c], xyz[name][f][None])[0])
            next_id += 1
    arrays = (np.array(field), np.array(camera), np.array(uv), np.array(marker))
    return (*arrays, dlts, np.array(truth))


def test_a_run_whose_blobs_come_from_two_markers_is_dropped() -> None:
    field, camera, uv, marker, dlts, truth = _table(ghost_from=6)
    out = drop_split_runs(marker, field, camera, uv, dlts, ReconParams(two_camera_split_mm=100.0))
    assert np.all(out[truth < 0] == -1)  # the whole ghost run, not only its first field
    assert np.all(out[truth >= 0] >= 0)  # the markers' own runs stay
    assert len(np.unique(out[out >= 0])) == 2 * 6


def test_markers_whose_blobs_continue_together_are_kept() -> None:
    field, camera, uv, marker, dlts, _ = _table(ghost_from=N_FIELDS)
    out = drop_split_runs(marker, field, camera, uv, dlts, ReconParams(two_camera_split_mm=100.0))
    assert np.array_equal(out >= 0, marker >= 0)
    assert len(np.unique(out)) == 2 * N_FIELDS
