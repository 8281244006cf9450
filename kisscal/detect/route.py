"""Which detection route a camera's images call for, from what they show.

Marker images (gait trials, wands, target dots) hold tens to a few hundred spots of a
size band, often with LED rings or dots larger than the specks around them; the blob
route (:mod:`kisscal.detect.pipeline`) with its merge, split and size tests is made for
them. Particle-tracking frames hold a crowd of small spots of every brightness on a dark
but textured background and nothing larger than a particle but glare: the peaks route
(:mod:`kisscal.detect.peaks`, after Maas et al. 1993) reads them as particle trackers do.

The survey's groups say which: the route is "peaks" when a frame holds at least
``peak_min_spots`` of them, ``peak_min_density`` per megapixel, most of them small (median
at most ``peak_small_spot_px`` pixels) and of many sizes (``peak_size_span``), falling off
with no population of larger spots of their own size (target dots, markers, LED rings:
:func:`marker_mode`). Its threshold is ``peak_noise_factor`` deviations of the
high-passed image's noise (these settings are :class:`DetectionParams` fields).

References
----------
Maas, H.-G., Gruen, A., & Papantoniou, D. (1993). Particle tracking velocimetry in
three-dimensional flows. Experiments in Fluids, 15(2), 133-146.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from kisscal.detect.params import DetectionParams
from kisscal.detect.survey import Groups

#: A bin of the size histogram (octaves) holding this many times the one below, and
#: :data:`MODE_EXTRA` more, is a population of its own (dots, markers, rings).
MODE_RISE = 1.25
MODE_EXTRA = 2
#: ... and at least this share of all the filled spots (not a few glare patches).
MODE_SHARE = 0.01


def particle_scene(
    groups: Groups, shape: tuple[int, ...], frames: int, params: DetectionParams | None = None
) -> tuple[bool, str]:
    """Whether surveyed ``groups`` are a particle scene (by the ``peak_*`` choice settings
    of ``params``, the defaults when None), and why, in words."""
    p = params or DetectionParams()
    if len(groups) == 0:
        return False, "no spots surveyed: blob route"
    per_frame = len(groups) / max(frames, 1)
    density = per_frame / (shape[0] * shape[1] / 1e6)
    low, median, high = np.percentile(groups.pixels, [10, 50, 90])
    bump = marker_mode(groups)
    facts = (
        f"{per_frame:.0f} spots a frame ({density:.0f} per megapixel), median {median:.0f} px, "
        f"10-90 % {low:.0f}-{high:.0f} px"
    )
    if bump is not None:
        return False, f"{facts}, a population of larger spots about {bump} px: blob route"
    crowd = per_frame >= p.peak_min_spots and density >= p.peak_min_density
    crowd = crowd and median <= p.peak_small_spot_px
    if crowd and high >= p.peak_size_span * max(low, 1.0):
        return True, f"particle frames ({facts}, no larger population): peaks route"
    return False, f"{facts}: blob route"


def marker_mode(groups: Groups) -> int | None:
    """Size (white pixels, a power of two) of a population of filled spots larger than the
    specks, or None: a bin of the octave histogram of the isolated filled spots' sizes,
    above its mode, holding :data:`MODE_RISE` times the bin below it (and a few more) and
    :data:`MODE_SHARE` of the spots.

    Particle images have every size, fewer the larger (each octave about half the one
    below); marker or dot images are a population of their own size among the specks.
    """
    spots = groups.pixels[groups.inside & (groups.fill > 0.6)]
    if spots.size == 0:
        return None
    counts = np.bincount(np.log2(np.maximum(spots, 1)).astype(int))
    above = np.arange(counts.size) > np.argmax(counts)
    rise = np.zeros(counts.size, dtype=bool)
    rise[1:] = counts[1:] >= MODE_RISE * counts[:-1] + MODE_EXTRA
    found = np.flatnonzero(rise & above & (counts >= MODE_SHARE * spots.size))
    return int(2 ** found[0]) if found.size else None


def highpass_noise(frames: Sequence[NDArray], side: int) -> float:
    """Robust deviation (1.4826 MAD) of the frames less their ``side`` box mean."""
    values = []
    for image in frames:
        grey = image.astype(np.float32, copy=False)
        diff = grey - cv2.blur(grey, (side, side), borderType=cv2.BORDER_REPLICATE)
        values.append(diff[::2, ::2].ravel())
    d = np.concatenate(values)
    return float(1.4826 * np.median(np.abs(d - np.median(d))))


def peak_settings(
    frames: Sequence[NDArray], params: DetectionParams | None = None
) -> dict[str, tuple[object, str]]:
    """The peaks route's derived settings for a camera's frames: value and reason."""
    p = params or DetectionParams()
    noise = highpass_noise(frames, p.peak_highpass_px)
    threshold = round(max(p.peak_noise_factor * noise, 1.0), 1)
    unbounded = "a particle image is bounded by its pixels (OpenPTV's size limits), not its extent"
    return {
        "threshold": (
            threshold,
            f"{p.peak_noise_factor:g} deviations of the high-passed noise ({noise:.1f}) above "
            f"the {p.peak_highpass_px} px box mean",
        ),
        "peak_min_sum_grey": (
            round(p.peak_sum_factor * threshold, 1),
            f"{p.peak_sum_factor:g} thresholds of summed high-passed grey",
        ),
        "max_width_px": (None, unbounded),
        "max_height_px": (None, unbounded),
    }


def choose_route(
    choose: Callable[[str, Any, str], Any],
    frames: Sequence[NDArray],
    groups: Groups,
    given: Mapping[str, Any] | None = None,
) -> None:
    """Record the route (and the peaks route's settings) through ``choose(name, value,
    why)``, which keeps a value the user gave; the ``peak_*`` settings the choice reads
    are the defaults or as ``given`` ([detection] values)."""
    params = DetectionParams.from_layers(given or {})
    chosen, why = particle_scene(groups, frames[0].shape, len(frames), params)
    if choose("route", "peaks" if chosen else "blobs", why) == "peaks":
        for name, (value, reason) in peak_settings(frames, params).items():
            choose(name, value, reason)
