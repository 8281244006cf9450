"""Which way is up, from the trial itself.

A shipped set's template stands on the floor with Z up, and the labelling's upright
steps (:mod:`~kisscal.tracking.labelling.upright`, :mod:`~kisscal.tracking.labelling.anatomy`)
turn the body about the vertical only. Labs do not agree on the vertical: Vicon and
Qualisys write Z up, NexGen, Phoenix and BTS Y up, and a file may say nothing
(``POINT:X_SCREEN``/``Y_SCREEN`` are optional and sometimes wrong). So the vertical is
found from the data (:func:`upright_rotation`):

1. **the tallest axis**: a standing or walking body is taller than it is wide or deep
   at any instant, so the lab axis along which the pieces seen in one field spread
   farthest (median over the first window's fields) is the vertical, up to its sign
   (axes spreading at least :data:`TALL_FRACTION` as far stay candidates);
2. **which end is the floor**: the first window's average pose, with each candidate
   (axis and sign) as up, is stood on the set's template (floor on floor) and fitted from
   every heading (:func:`~kisscal.tracking.labelling.upright.fit_on_floor`: the lowest
   piece on the floor, or the lab's own when the feet are not in view); a body stood on
   its head fits the standing template far worse (the capped cost), so the lowest cost
   wins. Lab Z up is kept unless another candidate fits clearly better
   (:data:`BETTER_FRACTION`).

The rotations are the lab axes' signed permutations with determinant +1, applied
exactly (no rounding): the labelling runs on the turned pieces and its trajectories are
turned back (:func:`turned`).
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from kisscal.markersets.model import MarkerSet
from kisscal.tracking.labelling.state import LabelState
from kisscal.tracking.labelling.upright import average_pose, fit_on_floor
from kisscal.tracking.labelling.window import first_pose
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.tracks import Tracks

#: Axes whose per-field spread is at least this fraction of the largest are candidates.
TALL_FRACTION = 0.75
#: The two ends of an axis fit alike when their capped costs are within this ratio; the
#: floor decides (:func:`floor_sign`).
SIGN_MARGIN = 0.9
#: One end of the body is steadier than the other when its spread over the fields is
#: below this fraction of the other's.
FLOOR_RATIO = 0.5
#: Another vertical than lab Z must fit the standing template with a capped cost below
#: this fraction of Z's.
BETTER_FRACTION = 0.8


def axis_rotation(axis: int, sign: int) -> NDArray[np.float64]:
    """The proper rotation (signed permutation, rows the new axes) taking lab ``axis``
    times ``sign`` to +Z."""
    eye = np.eye(3)
    return np.stack([eye[(axis + 1) % 3], sign * eye[(axis + 2) % 3], sign * eye[axis]])


def turned(tracks: Tracks, rotation: NDArray) -> Tracks:
    """``tracks`` with every position turned by ``rotation`` (3, 3): p -> rotation @ p."""
    return replace(
        tracks, xyz_mm=tracks.xyz_mm @ rotation.T, corrected_mm=tracks.corrected_mm @ rotation.T
    )


def field_spread(pos: NDArray) -> NDArray[np.float64]:
    """Median over fields of the extent (max - min) of the pieces seen, per lab axis."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # fields with no piece
        extent = np.nanmax(pos, axis=0) - np.nanmin(pos, axis=0)
        return np.nanmedian(extent, axis=0)


def upright_rotation(
    tracks: Tracks, marker_set: MarkerSet, params: TrackingParams
) -> NDArray[np.float64]:
    """Rotation (3, 3) turning the lab so that the trial's vertical is +Z (see the
    module's notes); the identity when the trial cannot tell (fewer than three long
    pieces, no pose).

    References
    ----------
    Besl & McKay 1992 (alternating assignment and fit, through
    :func:`~kisscal.tracking.labelling.upright.fit_on_floor`).
    """
    eye = np.eye(3)
    template = marker_set.template_mm
    state = LabelState.begin(tracks, marker_set.names, template, None, params)
    if state is None:
        return eye
    pos, _ = first_pose(state)
    spread = field_spread(pos)
    if not np.isfinite(spread).all():
        return eye
    cap = params.label_tolerance_mm
    costs = {}
    for axis in np.flatnonzero(spread >= TALL_FRACTION * spread.max()):
        for sign in (1, -1):
            r = axis_rotation(int(axis), sign)
            up = pos @ r.T
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # pieces never aligned
                pose = average_pose(up)
            seen = np.isfinite(pose[:, 0])
            if seen.sum() >= 3:
                costs[(int(axis), sign)] = fit_on_floor(pose[seen], up, template, cap)[0]
    if not costs:
        return eye
    best = min(costs, key=costs.get)
    other = (best[0], -best[1])
    if costs.get(other, np.inf) * SIGN_MARGIN <= costs[best]:
        # The standing template does not tell the ends apart: the floor does.
        floor = floor_sign(state.dense[..., best[0]])
        best = (best[0], floor or best[1])
    z_cost = costs.get((2, 1), np.inf)
    if best == (2, 1) or costs[best] >= BETTER_FRACTION * z_cost:
        return eye
    return axis_rotation(*best)


def floor_sign(height: NDArray) -> int:
    """+1 when the pieces' lowest point per field (``height``: pieces x fields) stays at
    one level (feet on the floor) and their highest does not, -1 the other way round, 0
    when neither end is clearly steadier (a still subject): the interquartile ranges over
    the fields must differ by :data:`FLOOR_RATIO`."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # fields with no piece
        low, high = np.nanmin(height, axis=0), np.nanmax(height, axis=0)
        spread = [np.subtract(*np.nanpercentile(v, [75, 25])) for v in (low, high)]
    if not np.isfinite(spread).all():
        return 0
    if spread[0] < FLOOR_RATIO * spread[1]:
        return 1
    return -1 if spread[1] < FLOOR_RATIO * spread[0] else 0
