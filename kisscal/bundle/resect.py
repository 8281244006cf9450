"""The wand's cameras written on the grid's own polynomial: DLT plus Kolahi's radial terms.

On a grid's linearisation the adjustment estimates Brown terms on the linearised pixels,
a small correction of what the grid's 30-coefficient polynomial left over. The written
files cannot carry Brown terms beside the grid's polynomial, and folding them into a new
polynomial (a fourth-order one cannot follow the r^4 term) costs more than they gain.
So each camera is resected instead (Kolahi et al. 2007, eqs. 1-3): a DLT with Kolahi's
radial terms L12..L14 (as many as ``resect_terms``) is fitted in pixels to the adjusted
wand markers and the rods' surveyed markers together with their linearised images,
thousands of points across the whole image and volume (the rods alone hold a lens model
only between the rods; here the wand fills the volume). Each source is weighed by the
inverse of its own image variance, as in the adjustment (``control.weight``, the ratio
of the wand's residual variance to the rods' by variance components, Förstner 1979): the
rods' few static markers are 8 times less noisy than the moving wand's, and weighed
equally their tens of points would count for nothing beside thousands. The grid's
polynomial is kept
as it is, and the DLT files carry the rest exactly, as the rods route writes its own
lens model.

References
----------
Förstner, W. (1979). Ein Verfahren zur Schätzung von Varianz- und Kovarianzkomponenten.
Allgemeine Vermessungs-Nachrichten 86, 446-453.

Kolahi, A., et al. (2007). Design of a marker-based human motion tracking system.
Biomedical Signal Processing and Control 2, 59-67.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from kisscal.bundle.adjust import BundleResult, ControlPoints, WandObservations, centred_offsets
from kisscal.bundle.params import BundleParams
from kisscal.camera import Camera
from kisscal.dlt import DltParams
from kisscal.dlt.nonlinear import refine_dlt
from kisscal.dlt.params import DEFAULT_PARAMS as DEFAULT_DLT


def resects(params: BundleParams, cameras: Sequence[Camera]) -> bool:
    """Whether cameras adjusted with ``params`` are written resected (``grid_lens``
    ``resect``, with lens terms estimated)."""
    return (
        params.grid_lens == "resect"
        and params.resect_terms > 0
        and any(c.has_brown for c in cameras)
    )


def final_cameras(
    result: BundleResult,
    observations: WandObservations,
    control: ControlPoints | None,
    markers_mm: Sequence[float],
    params: BundleParams,
    dlt: DltParams = DEFAULT_DLT,
) -> tuple[Camera, ...]:
    """The cameras as written: resected on the adjusted points when :func:`resects`,
    else the adjustment's own.

    Parameters
    ----------
    result : BundleResult
        An adjustment of ``observations`` (its ``inlier`` marks their rows).
    observations : WandObservations
    control : ControlPoints or None
        The rods' markers (surveyed positions and images), weighed ``control.weight``
        times a wand image.
    markers_mm : sequence of float
        The wand's markers.
    params : BundleParams
        ``grid_lens`` and ``resect_terms``.
    dlt : DltParams
        The session's DLT settings: the fit's iterations and tolerance (its model is
        set here: refined, with ``resect_terms`` of Kolahi's terms, no MDLT).

    Returns
    -------
    tuple of Camera
        Each a DLT with Kolahi's terms (``kolahi``) acting on the grid-linearised pixels.
    """
    if not resects(params, result.cameras):
        return result.cameras
    dlt = dlt.replace(refine=True, lens=True, lens_terms=params.resect_terms, mdlt=False)
    obs = observations.subset(result.inlier)
    offsets = centred_offsets(markers_mm)[obs.marker]
    wand_xyz = (
        result.wand.centre_mm[obs.field] + offsets[:, None] * result.wand.direction[obs.field]
    )
    out = []
    for c in range(len(result.cameras)):
        xyz, uv = [wand_xyz[obs.camera == c]], [obs.uv_px[obs.camera == c]]
        weight = [np.ones(len(xyz[0]))]
        if control is not None:
            rows = control.camera == c
            xyz.append(control.xyz_mm[rows])
            uv.append(control.uv_px[rows])
            weight.append(np.full(int(rows.sum()), control.weight))
        xyz, uv = np.concatenate(xyz), np.concatenate(uv)
        # started from the adjusted pinhole: the fit's own minimum, a few iterations
        # away, without the linear DLT's SVD of every point's two rows
        start = result.cameras[c].dlt
        L, lens, _ = refine_dlt(xyz, uv, start, dlt, weights=np.concatenate(weight))
        out.append(Camera.from_dlt(L, kolahi=lens))
    return tuple(out)
