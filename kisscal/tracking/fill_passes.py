"""The passes of the gap fills: which fills are tried on a gap's runs, in which order
(:data:`FILLS`, the first pass and the track ends; :data:`SECOND_PASS`;
:data:`LAST_PASS`; the trusted pass is
:data:`~kisscal.tracking.fill_trusted.TRUSTED_PASS`).
Each is a :class:`~kisscal.tracking.fill_table.Fill` with its reach; the runner that
applies a pass is :mod:`kisscal.tracking.fill_runner`, the passes' order over a trial's
tracks :func:`kisscal.tracking.gaps.fill_gaps_named`.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import numpy as np
from numpy.typing import NDArray

from kisscal.tracking.fill_body import end_body, spline_or_body
from kisscal.tracking.fill_centre import centre_body
from kisscal.tracking.fill_depth import depth_ray_fill
from kisscal.tracking.fill_ends import chain_end_fill, rays_end_fill
from kisscal.tracking.fill_held import held_body
from kisscal.tracking.fill_hip import hip_ray_fill
from kisscal.tracking.fill_joint import joint_ray_fill
from kisscal.tracking.fill_joint_depth import joint_depth_fill
from kisscal.tracking.fill_pair import merged_pair_fill
from kisscal.tracking.fill_place import take_placed
from kisscal.tracking.fill_sphere import sphere_depth_fill
from kisscal.tracking.fill_table import Fill
from kisscal.tracking.fill_unmerged import unmerged_depth_fill
from kisscal.tracking.gap_record import Gap
from kisscal.tracking.params import TrackingParams
from kisscal.tracking.raychain import chain_fill


def _ray_placer(method: Callable, *extra: str) -> Callable:
    """A fill of :data:`FILLS` from a single-camera placer ``method(dense, t, a, b, spare,
    params, *extra)`` (a :class:`~.on_rays.ChainFill` or None; ``extra`` names attributes of the
    gap): its fields written as context, their blobs taken (:func:`take_placed`)."""

    def fill(gap: Gap, a: int, b: int, params: TrackingParams) -> NDArray[np.bool_]:
        got = method(gap.dense, gap.t, a, b, gap.spare, params, *(getattr(gap, n) for n in extra))
        if got is None:
            return np.zeros(b - a, dtype=bool)
        gap.out.extend(take_placed(gap.dense, gap.t, a, got, gap.spare))
        return np.isfinite(got.sd_mm)

    return fill


#: The fills of a gap, in order: each is tried on the fields the ones before it left
#: (see :class:`Fill` for the reach of each). The marker's own blobs placed on their rays
#: by the segment's lengths to its measured markers (:func:`~.raychain.chain_fill`), then
#: with the segment's other markers on theirs (:func:`~.fill_joint.joint_ray_fill`); then
#: the spline (short runs) or the body (:func:`~.fill_body.spline_or_body`), only
#: expecting little error (``ray_rest_max_error_mm``) between fields placed on rays;
#: where it finds none, the blobs of one camera at a spline's distance from it
#: (:func:`~.fill_depth.depth_ray_fill`), or at the depth fitted to that spline and the
#: segment's lengths together (:func:`~.fill_sphere.sphere_depth_fill`), the body about a
#: marker and a joint centre (:func:`~.fill_centre.centre_body`), and the fields left
#: between them by the body expecting little error. At a named track's ends, once every
#: gap is filled: the point where two or more cameras' rays of the marker's blobs meet
#: (:func:`~.fill_ends.rays_end_fill`), the fields it left between them as a gap
#: (:func:`~.fill_body.spline_or_body`), the segment carrying it from one side
#: (:func:`~.fill_body.end_body`), then beyond, its blobs in one camera placed on their
#: rays by its segment's lengths
#: (:func:`~.fill_ends.chain_end_fill`; after the segment, which carried kiss 3 seed 303's
#: LTIB to 0.6 mm where one camera's ray took it to 2.3). Fields placed on rays have status
#: ``filled_rigid``, every one counted in ``ray_fields``.
#: Between the two, once every track's gaps are filled, and again after the ends, the
#: fields they left are tried again with the partners placed since
#: (:func:`~.fill_runner.second_pass`: a tibia hidden from every camera while the knee, seen by one,
#: is placed only at its track's end).
FILLS: tuple[Fill, ...] = (
    Fill(
        "chain", _ray_placer(chain_fill, "end", "errors", "absent", "mirror"), sweep=True, rays=True
    ),
    Fill("joint", _ray_placer(joint_ray_fill, "absent", "mirror"), sweep=True, rays=True),
    Fill("body", spline_or_body, strict="swept"),
    Fill("body where donors hold", held_body, long_run=True, strict="swept"),
    Fill("depth", _ray_placer(depth_ray_fill, "measured"), rays=True, long_run=True),
    Fill(
        "sphere depth",
        _ray_placer(sphere_depth_fill, "measured", "known", "expected", "mirror"),
        rays=True,
        long_run=True,
    ),
    Fill("body about a joint centre", centre_body, long_run=True, strict="swept"),
    Fill("body between rays", spline_or_body, split_only=True, strict="always"),
    Fill("end rays", _ray_placer(rays_end_fill, "end"), ends=True),
    Fill("end holes", spline_or_body, ends=True, enclosed=True),
    Fill("end", end_body, ends=True),
    Fill("end chain", _ray_placer(chain_end_fill, "end", "errors", "absent", "mirror"), ends=True),
)


#: The fills of the second pass (:func:`~.fill_runner.second_pass`): the marker's own
#: blobs placed on their rays by its segment's lengths, or at a smooth depth through the
#: joint fill's loose solutions (:mod:`.fill_joint_depth`; only what all else left: in the
#: first pass it took lowcost 311 RTOE, 6.7 mm off expecting 1.6), the rest by the body
#: expecting little error, a spline only where it expects little error too, counting the
#: samples it reads and their noise (:func:`~.fill_body.spline_or_body`'s ``checked``;
#: these runs lie beside what the first pass's checks refused: lowcost 303 RANK, a spline
#: to a wrong sample 49 mm off).
SECOND_PASS = (
    *(f for f in FILLS if f.name in ("chain", "joint")),
    Fill(
        "joint depth",
        _ray_placer(joint_depth_fill, "measured", "absent", "mirror"),
        rays=True,
        long_run=True,
    ),
    Fill("body", partial(spline_or_body, checked=True), strict="always"),
)


#: The last pass, after the ends: :data:`SECOND_PASS`, then on what it left the depth fitted to the
#: spline and the lengths of the partners placed since, their error counted, as their fills expect
#: it where two partners check each other (:mod:`.fill_sphere`; lowcost 306 LTHI: one camera, its
#: knee placed, the pelvis's sacrum only at its track's end, 0.9 mm expected: at
#: ``ray_rest_max_error_mm`` each, 39-44 expected 3.2-3.7 mm, 0.5-1.7 mm off, and stayed open). Not
#: before: a run it splits is walked by the chain fill from a placed edge (kiss 3 seed 306 RTIB, 4.6
#: mm RMS off expecting 2.7), and before the body it took lowcost 311 RANK on the toe's sphere 19.7
#: mm off. Then the marker solved with the pelvis carrying its hip centre on rays
#: (:mod:`.fill_hip`); last, the same depth on the rays of blobs merged with a neighbour placed by
#: then, its share out (:mod:`.fill_unmerged`), then both (:mod:`.fill_pair`), on any run (lowcost
#: 311, 361).
LAST_PASS = (
    *SECOND_PASS,
    *(f for f in FILLS if f.name == "sphere depth"),
    Fill("hip", _ray_placer(hip_ray_fill, "absent", "mirror", "errors"), rays=True, long_run=True),
    Fill("unmerged", _ray_placer(unmerged_depth_fill, "measured", "known", "expected", "mirror")),
    Fill("merged pair", _ray_placer(merged_pair_fill, "known", "mirror")),
)
