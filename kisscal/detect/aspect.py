"""Pixel aspect from the shapes of isolated markers: round markers, non-square pixels.

References
----------
Sen, P. K. (1968). Estimates of the regression coefficient based on Kendall's tau.
Journal of the American Statistical Association, 63, 1379-1389.
"""

from __future__ import annotations

import numpy as np

from kisscal.detect.shape import PIXEL_AREA_VAR
from kisscal.detect.survey import Groups

#: Fewest isolated spots for a pixel-aspect estimate.
MIN_SPOTS_FOR_ASPECT = 12
#: A measured pixel aspect this close to 1 is taken as square pixels.
SQUARE_TOLERANCE = 0.1
#: How far from 1 the spots' median spread ratio must be to call the pixels non-square
#: (it reads rounder than the truth: 1.94 pixels give about 1.7, 0.75 about 0.77).
RATIO_EVIDENCE = 0.15
#: Fewest places (spots of a static scene count once) for non-square pixels to be told.
MIN_PLACES_FOR_ASPECT = 30
#: Fewest white pixels of a spot whose shape says something about the pixels.
MIN_SPOT_PIXELS = 12


def measure_pixel_aspect(spots: Groups) -> tuple[float, str]:
    """Pixel aspect (width / height of a round marker's image) from isolated spots.

    Returns the value and the reason. Blur, blooming and the sensor widen every spot by
    about the same spread ``g`` (pixels) along both axes, so a round marker of spread
    ``s`` (scan lines) has grey-level spreads ``sigma_x = a s + g`` and
    ``sigma_y = s + g`` (the model of :mod:`kisscal.detect.shape`): over spots of many
    sizes, ``sigma_x`` is a straight line in ``sigma_y`` of slope ``a``, fitted robustly
    (Sen 1968). The spots' median spread ratio reads rounder than the truth but is
    steadier. Square pixels are the rule: the aspect differs from 1 only when the
    evidence is strong, that is when the ratio itself is :data:`RATIO_EVIDENCE` or more
    away from 1, over spots at :data:`MIN_PLACES_FOR_ASPECT` places or more, and the
    slope (if its 95 % interval is within a fifth of it) agrees with it in direction;
    the value is then the slope, else the ratio. Specks (fewer
    than :data:`MIN_SPOT_PIXELS` pixels) are left out: their shape is a few pixels.
    """
    ok = spots.inside & (spots.fill > 0.5) & (spots.pixels >= MIN_SPOT_PIXELS)
    ok &= (spots.var_x > PIXEL_AREA_VAR) & (spots.var_y > PIXEL_AREA_VAR)
    sx = np.sqrt(spots.var_x[ok] - PIXEL_AREA_VAR)
    sy = np.sqrt(spots.var_y[ok] - PIXEL_AREA_VAR)
    if sx.size < MIN_SPOTS_FOR_ASPECT:
        return 1.0, f"only {sx.size} isolated spots: square pixels assumed"
    ratio = float(np.median(sx / sy))
    if not np.isfinite(ratio) or ratio <= 0:
        return 1.0, "no consistent spot shape: square pixels assumed"
    how = f"median x / y spread of {sx.size} isolated spots {ratio:.3f}"
    if abs(ratio - 1.0) < RATIO_EVIDENCE:
        return 1.0, f"{how}: no strong evidence of non-square pixels, square assumed"
    # a static scene shows the same spots in every frame: count places, not sightings
    places = np.unique(np.round(np.column_stack([spots.x[ok], spots.y[ok]]) / 2.0), axis=0)
    if len(places) < MIN_PLACES_FOR_ASPECT:
        return 1.0, f"{how}, at only {len(places)} places: square pixels assumed"
    from scipy.stats import theilslopes  # here: scipy.stats takes ~1 s to import

    fit = theilslopes(sx, sy)
    spread = (fit.high_slope - fit.low_slope) / abs(fit.slope)
    aspect = ratio
    if spread <= 0.2:
        if (fit.slope - 1) * (ratio - 1) <= 0 or abs(fit.slope - 1) < SQUARE_TOLERANCE:
            return 1.0, f"{how}, slope {fit.slope:.3f} disagrees: square pixels assumed"
        aspect = float(fit.slope)
        how = f"slope of x on y spread over {sx.size} isolated spots (ratio {ratio:.3f})"
    if abs(aspect - 1.0) <= SQUARE_TOLERANCE:
        return 1.0, f"{how}: {aspect:.3f}, within {SQUARE_TOLERANCE:.0%} of square"
    return round(aspect, 3), how
