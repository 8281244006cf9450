"""Point channels of a C3D file that lab software computed and wrote beside the markers
without declaring them as model outputs: found from the data, not the labels (see
:func:`kisscal.io.c3d.read_c3d`)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

#: A channel with one coordinate exactly constant over at least this many valid samples,
#: while it moves by more than :data:`FLAT_MOVES_MM` along another, is not a measured
#: marker (below).
FLAT_MIN_SAMPLES = 10
FLAT_MOVES_MM = 1.0


def flat_channels(xyz_mm: NDArray) -> NDArray[np.bool_]:
    """Which channels have a coordinate exactly constant (to the bit) over every valid
    sample while the channel moves along another: a floor projection (Plug-in Gait's
    ``CentreOfMassFloor``, z = 0) or a scalar stored as a point (``LArchHeight``: x = y =
    0), which lab software writes beside the markers in no model-output group. A measured
    marker's coordinates carry its reconstruction noise, so none stays fixed to the bit
    while the marker moves. When most channels are flat in one coordinate the recording is
    planar and nothing is left out."""
    valid = np.isfinite(xyz_mm).all(axis=2)[..., None]
    high = np.where(valid, xyz_mm, -np.inf).max(axis=0, initial=-np.inf)
    low = np.where(valid, xyz_mm, np.inf).min(axis=0, initial=np.inf)
    span = high - low  # (n_channels, 3); -inf for a channel without a valid sample
    flat = (span == 0).any(axis=1) & (span > FLAT_MOVES_MM).any(axis=1)
    flat &= valid[..., 0].sum(axis=0) >= FLAT_MIN_SAMPLES
    return flat if 2 * flat.sum() <= len(flat) else np.zeros_like(flat)


#: Two channels whose samples of every frame lie closer than this are one marker: markers
#: are at least a diameter (6 mm and up) apart.
SAME_MARKER_MM = 5.0
#: Frames (evenly spaced) on which pairs of channels are first compared.
_PAIR_SAMPLE_FRAMES = 64


def copies(xyz_mm: NDArray) -> NDArray[np.bool_]:
    """Which channels are copies of another: valid only where the other is and within
    :data:`SAME_MARKER_MM` of it in every such frame (at least
    :data:`FLAT_MIN_SAMPLES` of them). The Oxford foot model writes a point at the heel
    marker (``LHE1``, 0.8 mm from ``LHEE`` in every frame), Motion Analysis Cortex its
    virtual markers (``VRTO`` on ``R.TO``), a Qualisys export every marker three times;
    fed to the tracker as a second point, one of the two becomes a one-sample trajectory
    in every frame (a Nexus trial with the Oxford foot model: 569 of them). Of the two,
    the one seen in fewer frames goes (the later one when both are seen alike)."""
    valid = np.isfinite(xyz_mm).all(axis=2)
    n_frames, n = valid.shape
    seen_together = np.zeros((n, n), dtype=bool)
    apart = np.zeros((n, n), dtype=bool)
    # candidates: close in every sampled frame where both are seen (a frame at a time:
    # files hold up to a few hundred channels)
    for f in np.unique(
        np.linspace(0, n_frames - 1, min(n_frames, _PAIR_SAMPLE_FRAMES)).astype(int)
    ):
        both = valid[f, :, None] & valid[f, None]
        with np.errstate(invalid="ignore"):
            far = np.linalg.norm(xyz_mm[f, :, None] - xyz_mm[f, None], axis=2) >= SAME_MARKER_MM
        seen_together |= both
        apart |= both & far
    candidate = seen_together & ~apart & ~np.eye(n, dtype=bool)
    copy = np.zeros(n, dtype=bool)
    for i, j in zip(*np.nonzero(np.triu(candidate)), strict=True):
        a, b = valid[:, i], valid[:, j]
        seen = a & b
        close = np.linalg.norm(xyz_mm[seen, i] - xyz_mm[seen, j], axis=1) < SAME_MARKER_MM
        if seen.sum() < FLAT_MIN_SAMPLES or not close.all() or copy[i]:
            continue
        if not (b & ~a).any():
            copy[j] = True
        elif not (a & ~b).any():
            copy[i] = True
    return copy
