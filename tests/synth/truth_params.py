"""Detection parameters derived by hand from a synthetic rig's truth (``truth/detection.json``).

The proof that a preset's rig is sound does not depend on detection configuring itself:
these parameters are what a careful technician would set knowing the truth (threshold
above the brightest background by six noise sigmas or 15 % of the marker plateau, the
true pixel aspect, size limits between the largest marker and the smallest LED ring).
The self-configured detection of issue 11 is compared against the figures they give.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Literal

import numpy as np

from kisscal.detect import DetectionParams
from kisscal.detect.pipeline import check_image

Kind = Literal["trials", "rods", "grid"]


def detection_units(dn: float, bit_depth: int) -> float:
    """A grey level of a recorded image (DN) in the units detection thresholds it in."""
    if bit_depth <= 8:
        return float(dn)
    probe = 1000
    return float(check_image(np.full((1, 1), probe, np.uint16))[0, 0]) * dn / probe


def _odd(x: float) -> int:
    n = math.ceil(x)
    return n if n % 2 else n + 1


def _largest(ranges: list[Mapping[str, Any]], level: str, key: str) -> float:
    return max(r[level][key][1] for r in ranges if r[level][key] is not None)


def _smallest(ranges: list[Mapping[str, Any]], level: str, key: str) -> float:
    return min(r[level][key][0] for r in ranges if r[level][key] is not None)


def threshold_dn(camera: Mapping[str, Any], kind: Kind) -> float:
    """Six noise sigmas or 15 % of the marker plateau above the brightest background."""
    background = camera["background"]["grid" if kind == "grid" else "trials_and_rods"]
    top = background["level_dn"][1]
    sigma = background["noise_sigma_dn"][1]
    return top + max(6 * sigma, 0.15 * camera["marker_peak_dn"])


def detection_params(
    camera: Mapping[str, Any], kind: Kind, blur_px: float
) -> tuple[DetectionParams, list[str]]:
    """Parameters for one camera's ``kind`` of images, and notes on limits that conflict.

    ``camera`` is one entry of ``truth/detection.json``'s ``cameras``. Markers (trials and
    rods alike) must fit under the size limits with a margin for noise at the rim; LED
    rings must not (a conflict is noted, the markers win).
    """
    notes: list[str] = []
    if kind == "grid":
        objects, oversize = [camera["grid_dots"]], None
    else:
        objects = [camera["markers"]["trials"], camera["markers"]["rods"]]
        objects = [o for o in objects if o["whole"]]
        oversize = camera["led_rings"] if camera["led_rings"]["whole"] else None
    big = {k: _largest(objects, "low", k) for k in ("pixels", "width_px", "height_px")}
    limit = {k: 1.3 * v + 2 for k, v in big.items()}
    if oversize is not None:  # the limits halfway between the markers and the LED rings
        for k in limit:
            led = _smallest([oversize], "half", k)
            if led > limit[k]:
                limit[k] = 0.5 * (limit[k] + led)
            else:
                notes.append(f"{camera['camera']}: an LED ring's {k} {led} is within markers'")
    small_pixels = _smallest(objects, "half", "pixels")
    # the blurred rim is worth adding to the weighted centroid where the background is
    # clean; under noise and glow it adds more error than light
    noise_8bit = camera["background"]["trials_and_rods"]["noise_sigma_dn"][1] * 255
    clean = noise_8bit / camera["max_value"] < 1.0
    margin = math.ceil(3 * blur_px) + 1 if clean else max(1, math.ceil(blur_px))
    params = DetectionParams(
        threshold=detection_units(threshold_dn(camera, kind), camera["bit_depth"]),
        pixel_aspect=float(camera["pixel_aspect"]),
        max_pixels=int(limit["pixels"]),
        max_width_px=int(limit["width_px"]),
        max_height_px=int(limit["height_px"]),
        min_pixels=int(max(2, small_pixels // 3)),
        submarker_max_pixels=int(max(2, min(8, small_pixels // 2))),
        detach_kernel_px=(_odd(big["width_px"] + 2), _odd(big["height_px"] + 2)),
        centroid_margin_x_px=margin,
        centroid_margin_y_px=margin,
    )
    return params, notes
