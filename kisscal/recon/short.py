"""Two-camera pieces too short to continue a trajectory, taken on their own evidence.

A marker that two cameras see for three fields or so, with no trajectory around it (a
trial's first fields, a leg seen for a moment between occlusions), is left out by
:func:`~kisscal.recon.pairs.choose_pairs`: four positions are needed to judge motion, and
by :func:`~kisscal.recon.body.body_pairs` when its segment's other markers are unknown.
A rig at 30 Hz meets such pieces more often than one at 50-60 Hz: a blob lost or merged
for a tenth of a second leaves fewer fields to the pairs around it (issue 27: lowcost
seeds 418-428, at 30 Hz, recall of markers seen by two cameras 96.9-97.8 %).

Among the candidate pairs left over, pairs that share neither blob with another and
recur on the same two cameras in :data:`SHORT_FIELDS` consecutive fields, within the
largest step the trial's known markers make and the continuity tolerance, are a marker
when every residual is that of a marker and not that of two unrelated rays crossing
inside the band: a crossing's residual spreads over the band up to the trial's limit, a
marker's stays near the trial's median (Hartley & Zisserman 2004, ch. 12: the
reprojection error as the measure of a correspondence). On the lowcost seeds at 30 Hz,
the pieces of two or more fields with every residual within
``two_camera_short_rms_factor`` times the median lay within 5 mm of a marker in all
fields but one (a 214 mm step, before the step limit).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from kisscal.recon.carried import links
from kisscal.recon.claimed import pieces
from kisscal.recon.params import ReconParams

#: Fields a piece needs: single-field pairs left over are mostly rays crossing metres
#: from the body; two-field pieces, right within 2 mm on lowcost seeds 373 and 403, left
#: the tracker short tracks it drops with the fills around them (coverage min 100 ->
#: 98.25 % and 96.07 -> 94.56 %), and 428's two-field pieces cost 18 identity switches.
SHORT_FIELDS = 3


def known_step_mm(
    xyz: NDArray[np.float64], field: NDArray[np.int64], step_mm: float, tolerance_mm: float
) -> float:
    """The largest step (mm) between consecutive points of the known markers'
    trajectories, where the step continues the one before within ``tolerance_mm``
    (:func:`~kisscal.recon.carried.links`): how far the trial's markers move in a field."""
    nxt, prv = links(xyz, field, step_mm, tolerance_mm)
    k = np.flatnonzero((nxt >= 0) & (prv >= 0))
    return float(np.linalg.norm(xyz[nxt[k]] - xyz[k], axis=1).max()) if len(k) else 0.0


def short_pieces(
    pairs: tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64], NDArray[np.int64]],
    rms_px: NDArray[np.float64],
    won: NDArray[np.bool_],
    camera: NDArray[np.int64],
    known: tuple[NDArray[np.float64], NDArray[np.int64], float],
    params: ReconParams,
) -> NDArray[np.bool_]:
    """``won`` with the short pieces of unshared candidate pairs added (see module).

    Parameters
    ----------
    pairs : tuple of ndarray
        Candidate pairs: blobs ``a``, ``b`` (n,), points (n, 3) and fields (n,).
    rms_px : ndarray, shape (n,)
        Each pair's reprojection residual (px).
    won : ndarray of bool, shape (n,)
        Pairs taken so far; their blobs are used.
    camera : ndarray of int
        Camera of every blob.
    known : tuple
        The known markers' points (m, 3), fields (m,) and residuals (m,) (px).
    params : ReconParams
        ``two_camera_short_rms_factor``, ``two_camera_step_mm``,
        ``two_camera_continuity_mm``.

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    a, b, xyz, field = pairs
    known_xyz, known_field, known_rms = known
    n = int(max(a.max(initial=-1), b.max(initial=-1))) + 1
    used = np.zeros(n, dtype=bool)
    used[a[won]] = used[b[won]] = True
    free = ~won & ~used[a] & ~used[b]
    degree = np.bincount(np.r_[a[free], b[free]], minlength=n)
    k = np.flatnonzero(free & (degree[a] == 1) & (degree[b] == 1))
    tol = params.two_camera_continuity_mm
    step = known_step_mm(known_xyz, known_field, params.two_camera_step_mm, tol)
    if len(k) == 0 or step <= 0:
        return won
    typical_px = float(np.median(known_rms))  # a marker's residual in this trial
    cams = np.sort(np.column_stack([camera[a[k]], camera[b[k]]]), axis=1)
    label = pieces(xyz[k], field[k], cams, step, tol)
    crossing = np.zeros(label.max() + 1, dtype=bool)
    np.logical_or.at(crossing, label, rms_px[k] > params.two_camera_short_rms_factor * typical_px)
    take = (np.bincount(label)[label] >= SHORT_FIELDS) & ~crossing[label]
    out = won.copy()
    out[k[take]] = True
    return out
