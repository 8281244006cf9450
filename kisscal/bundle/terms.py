"""How many lens terms the trials' markers hold (issue 25).

The rods and the trials adjusted together (:mod:`kisscal.bundle.points`) estimate every
``[wand] lens_terms`` term of every camera. With a session's calibration trials alone
(tens of markers seen by three cameras) the terms beyond the first fit those markers no
better than the first alone: the rods' 24 markers, weighed ten times, then decide them, as
they decide the rods' own lens model, and the volume between and beyond the rods pays
(lowcost:72, 66 markers: 31 % worse than the best single model, the first term alone
within 3 %). Photogrammetry's self-calibration keeps an additional parameter only when
the observations show it significant (Gruen 1978; Fraser 1997). Here the adjustment is
refitted with the first term alone and the rest kept only when Akaike's information
criterion on the trials' image residuals prefers them (Akaike 1974): their markers must
fit better by more than the terms' count, in log-likelihood. Akaike's rather than
Schwarz's criterion because the aim is the smallest error in the volume, which Akaike's
estimates (Burnham & Anderson 2002), not the one true model: with 5000 residuals
Schwarz's penalty, 8.6 per term, barely kept the terms kiss:71's lens needs (163 against
154; its first term alone was 50 % worse there).

References
----------
Akaike, H. (1974). A new look at the statistical model identification. IEEE Transactions
on Automatic Control 19(6), 716-723.
Gruen, A. (1978). Accuracy, reliability and statistics in close-range photogrammetry.
Inter-Congress Symposium, ISPRS Commission V, Stockholm.
Fraser, C. S. (1997). Digital camera self-calibration. ISPRS Journal of Photogrammetry
and Remote Sensing 52, 149-159.
Burnham, K. P., & Anderson, D. R. (2002). Model selection and multimodel inference, 2nd
ed. Springer.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from kisscal.bundle.adjust import BundleResult, ControlPoints, WandObservations, adjust_bundle
from kisscal.bundle.params import BundleParams
from kisscal.camera import LENS_TERMS, Camera


def fewest_terms(
    result: BundleResult,
    observations: WandObservations,
    markers_mm: tuple[float, ...],
    control: ControlPoints,
    params: BundleParams,
) -> tuple[BundleResult, BundleParams]:
    """The adjustment with the lens terms its wand (trial) observations support.

    Parameters
    ----------
    result : BundleResult
        The adjustment with every ``params.lens_terms`` term.
    observations : WandObservations
        Its observations (the trials' markers).
    markers_mm : tuple of float
        The wand's marker offsets (a free point: ``(0.0,)``).
    control : ControlPoints
        The weighed control points of that adjustment.
    params : BundleParams

    Returns
    -------
    result : BundleResult
        ``result``, or the adjustment with the first lens term alone when Akaike's
        criterion on the observations' residuals does not prefer every term.
    params : BundleParams
        The parameters of the adjustment returned (its ``lens_terms``).
    """
    if len(params.lens_terms) < 2:
        return result, params
    fewer = replace(params, lens_terms=params.lens_terms[:1])
    start = tuple(_without(c, fewer.lens_terms) for c in result.cameras)
    small = adjust_bundle(start, observations, markers_mm, result.wand, control, fewer)
    # the same observations for both: an outlier of either is left out of the comparison
    both = result.inlier & small.inlier
    n = 2 * int(both.sum())
    rss_all = float(np.sum(result.residuals_px[both] ** 2))
    rss_few = float(np.sum(small.residuals_px[both] ** 2))
    extra = (len(params.lens_terms) - len(fewer.lens_terms)) * len(result.cameras)
    if rss_all > 0 and n * np.log(rss_few / rss_all) > 2 * extra:
        return result, params
    return small, fewer


def _without(camera: Camera, kept: tuple[str, ...]) -> Camera:
    """``camera`` with its Brown terms other than ``kept`` set to zero."""
    lens = np.array(camera.lens, dtype=float)
    drop = [k for k, term in enumerate(LENS_TERMS) if term not in kept and k < len(lens)]
    lens[drop] = 0.0
    return replace(camera, lens=lens)
