"""Pixel aspect from the shapes of isolated markers: round markers, non-square pixels.

References
----------
Sen, P. K. (1968). Estimates of the regression coefficient based on Kendall's tau.
Journal of the American Statistical Association, 63, 1379-1389.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import theilslopes

from kisscal.detect.shape import PIXEL_AREA_VAR
from kisscal.detect.survey import Groups

#: Fewest isolated spots for a pixel-aspect estimate.
MIN_SPOTS_FOR_ASPECT = 12
#: A measured pixel aspect this close to 1 is taken as square pixels.
SQUARE_TOLERANCE = 0.05


def measure_pixel_aspect(spots: Groups) -> tuple[float, str]:
    """Pixel aspect (width / height of a round marker's image) from isolated spots.

    Returns the value and the reason. Blur, blooming and the sensor widen every spot by
    about the same spread ``g`` (pixels) along both axes, so a round marker of spread
    ``s`` (scan lines) has grey-level spreads ``sigma_x = a s + g`` and
    ``sigma_y = s + g`` (the model of :mod:`kisscal.detect.shape`): over spots of many
    sizes, ``sigma_x`` is a straight line in ``sigma_y`` of slope ``a``, fitted robustly
    (Sen 1968). Spots all of one size cannot separate ``a`` from ``g``; when the slope's
    95 % interval is wider than a fifth of it, or it disagrees in direction with the
    spots' median spread ratio, that ratio (which reads rounder than the truth) is used.
    """
    ok = spots.inside & (spots.fill > 0.5) & (spots.pixels >= 6)
    ok &= (spots.var_x > PIXEL_AREA_VAR) & (spots.var_y > PIXEL_AREA_VAR)
    sx = np.sqrt(spots.var_x[ok] - PIXEL_AREA_VAR)
    sy = np.sqrt(spots.var_y[ok] - PIXEL_AREA_VAR)
    if sx.size < MIN_SPOTS_FOR_ASPECT:
        return 1.0, f"only {sx.size} isolated spots: square pixels assumed"
    ratio = float(np.median(sx / sy))
    # a static scene shows the same spots in every frame: count places, not sightings
    places = np.unique(np.round(np.column_stack([spots.x[ok], spots.y[ok]]) / 2.0), axis=0)
    fit = theilslopes(sx, sy) if len(places) >= 30 else None
    spread = (fit.high_slope - fit.low_slope) / abs(fit.slope) if fit is not None else np.inf
    if fit is not None and spread <= 0.2 and (fit.slope - 1) * (ratio - 1) >= 0:
        aspect = float(fit.slope)
        how = f"slope of x on y spread over {sx.size} isolated spots"
    else:  # sizes too alike (or too scattered) for a slope: the ratio, rounder than true
        aspect = ratio
        how = f"median x / y spread of {sx.size} isolated spots"
    if not np.isfinite(aspect) or aspect <= 0:
        return 1.0, "no consistent spot shape: square pixels assumed"
    if abs(aspect - 1.0) <= SQUARE_TOLERANCE:
        return 1.0, f"{how}: {aspect:.3f}, within 5 % of square"
    return round(aspect, 3), how
