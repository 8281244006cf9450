"""A spline fill does not go through a measured sample at its gap's edge whose blob holds
another marker's image merged with the marker's (lowcost 4 seed 437: an ankle's blob
merged with the toe's, the sample 23 mm off, the spline through it 24 mm RMS off
expecting 6.1) (kisscal.tracking.gaps, kisscal.tracking.fill_donors)."""

from __future__ import annotations

import numpy as np

from kisscal.dlt.model import project_rows
from kisscal.tracking import TrackingParams, spare_blobs
from kisscal.tracking.fill_body import spline_or_body
from kisscal.tracking.fill_donors import merged_edges
from kisscal.tracking.gap_record import Gap
from kisscal.tracking.segment_lengths import length_partners
from tests.tracking.test_fill_donors import _rolling_foot
from tests.tracking.test_rayfill import _look_at

PARAMS = TrackingParams()
LO, HI = 200, 204  # the ankle's gap; its sample at HI measured on a merged blob


def _ankle_gap(pull_mm: float, behind: bool = True) -> tuple[np.ndarray, np.ndarray, object]:
    """Truth and measured samples of the rolling foot (ankle 0, toe 1, heel 2), the ankle
    out over [LO, HI) and its sample at HI ``pull_mm`` towards the toe, and one camera
    behind the ankle from the toe (``behind``; else from the side): the ankle's own blobs
    in the gap, at HI one blob at the centroid of the ankle's and the toe's images where
    they lie within 3 px (used by the ankle's point)."""
    xyz = _rolling_foot(4)
    ankle, toe = xyz[0, HI], xyz[1, HI]
    sight = (ankle - toe) if behind else np.cross(toe - ankle, [0.0, 0.0, 1.0])
    dlts = _look_at(ankle + 3000.0 * sight / np.linalg.norm(sight), ankle)[None]
    fields = np.arange(LO, HI + 1)
    cam = np.zeros(fields.size, dtype=int)
    uv = project_rows(dlts, cam, xyz[0, fields])
    toe_uv = project_rows(dlts, cam[:1], toe[None])[0]
    if np.linalg.norm(toe_uv - uv[-1]) < 3.0:
        uv[-1] = 0.5 * (uv[-1] + toe_uv)
    point = np.r_[np.full(fields.size - 1, -1), 0]
    spare = spare_blobs(fields, cam, uv, dlts, point)
    dense = xyz.copy()
    dense[0, LO:HI] = np.nan
    dense[0, HI] += pull_mm * (toe - ankle) / np.linalg.norm(toe - ankle)
    return xyz, dense, spare


def _spline(dense: np.ndarray, spare: object) -> tuple[np.ndarray, float]:
    """The ankle's fill of [LO, HI) by :func:`spline_or_body` (a spline moved onto the rays) and
    its expected error."""
    gap = Gap(dense, 0, LO, HI, PARAMS, spare, np.isfinite(dense[0, :, 0]), np.zeros(4, bool), [])
    spline_or_body(gap, LO, HI, PARAMS)
    assert len(gap.out) >= 1
    xyz = np.concatenate([x for x, _ in gap.out])
    return xyz, max(f.expected_error_mm for _, f in gap.out)


def test_a_spline_does_not_go_through_an_edge_sample_on_a_merged_blob():
    xyz, dense, spare = _ankle_gap(20.0)
    partners = length_partners(dense, 0, PARAMS)[0]
    assert merged_edges(dense, 0, LO, HI, spare, PARAMS, partners) == [HI]
    got, expected = _spline(dense, spare)
    err = float(np.sqrt(np.mean(np.sum((got - xyz[0, LO:HI]) ** 2, axis=1))))
    assert err <= 2.0 * expected + 1.0


def test_an_edge_sample_on_the_marker_s_own_blob_is_kept():
    # a camera from the side: the toe's image far from the ankle's, its blob its own
    _, dense, spare = _ankle_gap(0.0, behind=False)
    partners = length_partners(dense, 0, PARAMS)[0]
    assert merged_edges(dense, 0, LO, HI, spare, PARAMS, partners) == []
