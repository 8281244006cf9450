"""Ground truth for blob detection: what a detector configured from the images should find.

Per camera of a synthetic session (``truth/detection.json``): the true pixel aspect, bit
depth, noise, background light, and the sizes of the marker images (trials and rods),
grid dots and LED rings. Sizes are measured on the noise-free rendering, in the recorded
image's grey levels (DN), at two levels above the local background (see
:data:`kisscal.synth.scene.SIZE_LEVELS`): half the marker plateau (the outline) and a
tenth of it (the blurred rim included). Only whole spots that share their light with no
other spot count; the outline diameter (bloom included) is given as well.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from kisscal.synth.plan import SynthPlan, camera_glow, grid_scene, rod_scene
from kisscal.synth.render import Spots, SpotSizes
from kisscal.synth.scene import SIZE_LEVELS, measure_sizes


def _span(values: NDArray) -> list[float] | None:
    """[min, max] of the finite values (None when there are none)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return [round(float(v.min()), 3), round(float(v.max()), 3)] if len(v) else None


def size_ranges(
    diameters_px: NDArray[np.float64], sizes: Mapping[str, SpotSizes], whole: NDArray[np.bool_]
) -> dict[str, Any]:
    """Ranges of the outline diameters (n, 2) and of the sizes at each level, over ``whole``.

    ``whole`` selects the spots that are one spot's image, uncut and alone.
    """
    whole = np.asarray(whole, dtype=bool)
    out: dict[str, Any] = {
        "count": len(whole),
        "whole": int(whole.sum()),
        "diameter_px": {
            "width": _span(diameters_px[whole, 0]),
            "height": _span(diameters_px[whole, 1]),
        },
    }
    for level, s in sizes.items():
        keep = whole & np.isfinite(s.pixels)
        out[level] = {
            "width_px": _span(s.width_px[keep]),
            "height_px": _span(s.height_px[keep]),
            "pixels": _span(s.pixels[keep]),
        }
    return out


def spots_ranges(scene: NDArray[np.float64], spots: Spots, plan: SynthPlan) -> dict[str, Any]:
    """:func:`size_ranges` of ``spots`` in a noise-free ``scene`` (whole: measured alone)."""
    sizes = measure_sizes(scene, spots, plan.render)
    whole = np.isfinite(sizes["low"].pixels)
    return size_ranges(2 * spots.radii_px, sizes, whole)


def _background(plan: SynthPlan, light: NDArray[np.float64] | None) -> dict[str, Any]:
    """Background grey levels (DN) and the noise sigma on them."""
    r = plan.render
    levels = (
        np.array([r.background, r.background])
        if light is None
        else np.array([light.min(), light.max()])
    )
    sigma = np.sqrt(r.noise_sigma**2 + (levels / r.electrons_per_dn if r.electrons_per_dn else 0))
    return {"level_dn": _span(levels * r.dn_scale), "noise_sigma_dn": _span(sigma * r.dn_scale)}


def camera_detection_truth(
    plan: SynthPlan, cam_index: int, trials: Mapping[str, Any]
) -> dict[str, Any]:
    """The detection truth of one camera; ``trials`` holds its trial markers' ranges."""
    cam = plan.rig[cam_index]
    r = plan.render
    view, grid_light, grid_background = grid_scene(plan, cam_index)
    markers, leds, rod_light = rod_scene(plan, cam_index)
    room = camera_glow(plan, cam_index)
    return {
        "camera": cam.id,
        "size_px": list(cam.size_px),
        # width / height of a round marker's image (the detection's pixel_aspect)
        "pixel_aspect": float(cam.K[0, 0] / cam.K[1, 1]),
        "bit_depth": r.bit_depth,
        "max_value": 2**r.bit_depth - 1,
        "marker_peak_dn": round(r.marker_peak * r.dn_scale, 3),
        "levels_dn": {k: round(f * r.marker_peak * r.dn_scale, 3) for k, f in SIZE_LEVELS.items()},
        "noise": {
            "read_sigma_dn": round(r.noise_sigma * r.dn_scale, 4),
            "electrons_per_dn": round(r.electrons_per_dn / r.dn_scale, 4),
            "noise_pixels_per_image": r.noise_pixels,
        },
        "background": {
            "trials_and_rods": _background(plan, room),
            "grid": _background(plan, grid_background),
        },
        "markers": {"trials": dict(trials), "rods": spots_ranges(rod_light, markers, plan)},
        "grid_dots": spots_ranges(grid_light, view.spots, plan),
        "led_rings": spots_ranges(rod_light, leds, plan),
    }


def session_detection_truth(plan: SynthPlan, cameras: list[dict[str, Any]]) -> dict[str, Any]:
    """``truth/detection.json``: the rig's description and every camera's truth."""
    o, r = plan.options, plan.render
    return {
        "preset": o.rig.preset,
        "rate_hz": o.rate_hz,
        "marker_radius_mm": round(r.marker_radius_mm, 3),
        "blur_px": r.blur_px,
        "bloom_px": r.bloom_px,
        "led_flare_px": r.led_flare_px,
        "level_fractions": dict(SIZE_LEVELS),
        "cameras": cameras,
    }
