"""Detection settings derived from a camera's own images.

Shafiq et al. (2001, section 3) tuned their thresholds and size limits to the KISS
cameras by hand. A lab with other cameras would have to do the same for every camera;
kisscal measures instead (:mod:`kisscal.detect.survey`) and decides here, for each
camera-dependent setting the user did not give:

- **threshold** and **background**: markers are a small bright population over a dark
  background. The threshold sits at 15 % of the contrast of the faint end of that
  population (5th percentile of the groups' peaks), low so that small far markers stay
  at least two lines tall and keep their shape, and at least five noise deviations above
  the background. When the background is uneven by more than half that margin, it is
  taken locally (tiles of four of the largest marker diameters; two where it is lit at
  the markers' own scale, as walls of a real scene) and the threshold counts from it.
- **pixel aspect**: isolated markers are round, so their width over their height is the
  pixel aspect. Thresholding widens every spot by about the same number of pixels in x and
  y, which pulls small spots towards round; the slope of the spots' x spread against their
  y spread over spots of many sizes (a robust Theil-Sen line) removes that. 1.0 when the
  measure is within 5 % of it or there are too few spots to tell.
- **size limits** (LED rings, reflections): in log area, markers form one population and
  the LED rings of facing cameras another, far larger. The upper limits sit between (at
  most twice the largest marker seen, for markers that come nearer than in any surveyed
  frame); the opening kernel that detaches markers from LED rings is a fifth larger than
  the largest marker.
- **centroid margins**: how far the blurred rim of the spots reaches beyond their white
  pixels, measured in x and y.

Grid images are surveyed on their own (300 near-identical dots give their own size). A
crowd of small spots with nothing marker-sized is particle frames: :mod:`~.route`.

References
----------
Shafiq, M. S., Tümer, S. T., & Güler, H. C. (2001). Marker detection and trajectory
generation algorithms for a multicamera based gait analysis system. Mechatronics, 11(4).
Sen, P. K. (1968). Estimates of the regression coefficient based on Kendall's tau.
Journal of the American Statistical Association, 63(324), 1379-1389.

Examples
--------
>>> import numpy as np
>>> from kisscal.detect import detect_blobs
>>> rng = np.random.default_rng(0)
>>> frames = []
>>> for _ in range(3):
...     image = rng.normal(10, 1, (200, 300)).clip(0, 255)
...     for x, y in rng.uniform(20, [280, 180], (40, 2)):
...         yy, xx = np.ogrid[:200, :300]
...         image += 200 * np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / (2 * 2.0**2))
...     frames.append(image.clip(0, 255).astype(np.uint8))
>>> setup = configure_detection(frames)
>>> setup.params.pixel_aspect
1.0
>>> len(detect_blobs(frames[0], setup.params).valid_only()) >= 35
True
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from kisscal.detect.aspect import MIN_SPOTS_FOR_ASPECT, measure_pixel_aspect
from kisscal.detect.clipped import crowd_notes, faint_sample
from kisscal.detect.extent import marker_extent
from kisscal.detect.params import DetectionParams
from kisscal.detect.pipeline import check_image, threshold_image
from kisscal.detect.points import choose_noise_removal
from kisscal.detect.polarity import frames_polarity
from kisscal.detect.population import largest_size, marker_population, odd_size
from kisscal.detect.roundness import cut_singles_reason, shapes_off_reason
from kisscal.detect.route import choose_route
from kisscal.detect.survey import (
    GreyLevels,
    Groups,
    grey_levels,
    marker_mask,
    rim_reach_px,
    structure_share,
    survey_frames,
)
from kisscal.errors import InputError

#: What the images are of: markers (trials, rods, axes, wand) or the linearisation grid.
Kind = Literal["markers", "grid"]

#: The settings this module derives; everything else keeps its default unless given.
DERIVED = (
    "threshold",
    "background_tile_px",
    "pixel_aspect",
    "max_pixels",
    "max_width_px",
    "max_height_px",
    "detach_kernel_px",
    "min_pixels",
    "centroid_margin_x_px",
    "centroid_margin_y_px",
    "centroid_highpass_px",
)

#: Fraction of the faint markers' contrast at which the threshold sits.
THRESHOLD_FRACTION = 0.15
#: The smallest oversized blob at least this many times the largest markers (area,
#: width, height) is another population: the upper limits sit between the two.
OVERSIZE_GAP = 1.5
#: Headroom of the upper size limit over the largest marker seen (area).
SIZE_HEADROOM = 2.0
#: Side of the band-pass centroid's mean, in largest-marker widths.
HIGHPASS_SIDE = 0.9
#: Largest share of the image whose background may be lit at the markers' scale (above
#: the white test's margin over the 4-diameter tile background) for those tiles to stay.
STRUCTURE_SHARE_MAX = 0.02
MIN_TILE_PX = 16  # smallest background tile (px)


@dataclass(frozen=True)
class Choice:
    """One setting: its value, whether it was given or derived, and why."""

    value: Any
    source: Literal["given", "derived", "default"]
    why: str = ""


@dataclass(frozen=True)
class DetectionSetup:
    """Detection parameters for one camera and kind of image, with the reasons.

    Attributes
    ----------
    params : DetectionParams
        Ready for :func:`kisscal.detect.detect_blobs`.
    choices : dict of str -> Choice
        Every camera-dependent setting (:data:`DERIVED`): value, source and reason.
    kind : {"markers", "grid"}
    frames : int
        Frames surveyed.
    levels : GreyLevels
        Background, noise and unevenness measured.
    marker_pixels : (int, int)
        Smallest and largest white-pixel count of the markers seen within the upper size
        limit (moving glare may join the marker population but is oversized).
    """

    params: DetectionParams
    choices: dict[str, Choice]
    kind: str
    frames: int
    levels: GreyLevels
    marker_pixels: tuple[int, int] = (0, 0)
    notes: tuple[str, ...] = field(default=())

    def summary(self) -> str:
        """One line for the run log."""
        p = self.params
        given = [k for k, c in self.choices.items() if c.source == "given"]
        level = (
            f"{p.threshold:.0f} grey levels above the local background (tiles "
            f"{p.peak_highpass_px if p.route == 'peaks' else p.background_tile_px} px"
            if p.background_tile_px or p.route == "peaks"
            else f"{p.threshold:.0f} (grey level; background {self.levels.background:.0f}"
        )
        limit = "none" if p.max_pixels is None else f"{p.max_pixels}"
        spots = "dark spots, inverted" if p.polarity == "dark" else f"{p.polarity} spots"
        text = (
            f"{self.kind} ({spots}, {p.route} route): threshold {level}, noise "
            f"{self.levels.noise:.1f}), pixel aspect {p.pixel_aspect:.2f}, markers "
            f"{self.marker_pixels[0]}-{self.marker_pixels[1]} px, oversize above {limit} px"
        )
        return text + (f"; given: {', '.join(given)}" if given else "")


def configure_detection(
    images: Sequence[NDArray],
    given: Mapping[str, Any] | None = None,
    *,
    kind: Kind = "markers",
    pixel_aspect: float | None = None,
    aspect_why: str = "known for this camera",
) -> DetectionSetup:
    """Detection parameters for a camera from a sample of its frames.

    Parameters
    ----------
    images : sequence of ndarray
        A few frames of one camera and one kind (5-30 spread over the recording are
        plenty); grey (8- to 16-bit) or already thresholded (boolean).
    given : mapping, optional
        Settings the user gave (``[detection]``); they are used as given.
    kind : {"markers", "grid"}
        Marker images (trials, rods, axes, wand) or images of the linearisation grid.
    pixel_aspect : float, optional
        The camera's pixel aspect when already known (e.g. from its grid lattice);
        measured from these images otherwise.
    aspect_why : str
        Where a known ``pixel_aspect`` comes from (for the record).

    Returns
    -------
    DetectionSetup
    """
    given = {k: v for k, v in (given or {}).items() if (k, v) != ("polarity", "auto")}
    base = DetectionParams.from_layers(given)  # unknown names and bad values: one-line errors
    frames = [check_image(im) for im in images]
    if not frames:
        raise InputError("detect: no images to derive the detection settings from")
    polarity = frames_polarity(frames, base.polarity)  # dark dots on white: inverted
    frames = polarity[2]
    if any(f.dtype == np.bool_ for f in frames):
        return _thresholded(base.replace(polarity=polarity[0]), given, kind, len(frames))
    raw_max = [float(np.max(im)) for im in images]
    shape = frames[0].shape
    survey_tile = max(32, min(shape) // 8)
    wide = [
        np.iinfo(im.dtype).max + 1 for im in images if np.issubdtype(im.dtype, np.unsignedinteger)
    ]
    levels = grey_levels(frames, raw_max, survey_tile, max(wide, default=256))
    known = None if pixel_aspect is None else (float(pixel_aspect), aspect_why)
    derivation = _Derivation(frames, given, kind, levels, known)
    derivation.choose("polarity", *polarity[:2])
    return derivation.run()


def _thresholded(
    params: DetectionParams, given: Mapping[str, Any], kind: str, n: int
) -> DetectionSetup:
    levels = GreyLevels(0.0, 0.0, 0.0, 1.0, 1)
    choices = {
        k: Choice(getattr(params, k), "given" if k in given else "default", "thresholded images")
        for k in ("polarity", *DERIVED)
    }
    return DetectionSetup(params, choices, kind, n, levels, notes=("images are binary",))


class _Derivation:
    """The decisions, in order; each records its :class:`Choice`."""

    def __init__(
        self,
        frames: list[NDArray],
        given: dict[str, Any],
        kind: str,
        levels: GreyLevels,
        known_aspect: tuple[float, str] | None,
    ) -> None:
        self.frames = frames
        self.given = given
        self.kind = kind
        self.levels = levels
        self.known_aspect = known_aspect
        self.choices: dict[str, Choice] = {}
        self.notes: list[str] = []
        self.values: dict[str, Any] = {}
        self.marker_width = 0.0  # of the largest markers at the survey's probe level (px)

    def choose(self, name: str, value: Any, why: str) -> Any:
        """Record a derived value unless the user gave one; return what holds."""
        if name in self.given:
            self.choices[name] = Choice(self.given[name], "given", "from [detection]")
            return self.given[name]
        self.choices[name] = Choice(value, "derived", why)
        self.values[name] = value
        return value

    def run(self) -> DetectionSetup:
        lv = self.levels
        probe = max(6.0 * lv.noise, 4.0 * lv.unit, 0.02 * (lv.top - lv.background))
        tile0 = max(32, min(self.frames[0].shape) // 8)
        # the first survey gives sizes and contrast only: its shapes are never read
        first = survey_frames(self.frames, probe, tile0, shapes=False)
        if len(first) == 0:
            return self._nothing_bright(probe)
        markers0, top0 = marker_population(first)
        self.marker_width = largest_size(first.width[markers0]) if markers0.any() else 0.0
        self._threshold(faint_sample(first, markers0, top0, lv))  # clipped: objects' size
        final = self._final_groups()
        self.notes.extend(crowd_notes(self.frames, self._partial_params()))  # in the specks?
        markers, top = marker_population(final)
        self._aspect(final.take(markers & (final.isolation > 3.0)))
        self._size_limits(final, markers, top)
        self._margins()
        seen = final.pixels[markers]
        if self.kind == "grid":
            for name in ("split_touching", "split_overlaps", "split_long_wide"):
                self.choose(name, False, "grid dots never touch: nothing to split")
        else:
            self._shape_tests(final.take(markers & (final.isolation > 2.0)))
            choose_route(self.choose, self.frames, final, self.given)  # particle frames?
            choose_noise_removal(self.choose, self.frames, self._partial_params(), seen)
        params = DetectionParams.from_layers(self.values, self.given)
        if params.max_pixels is not None:  # the band printed is the one the limits keep
            seen = seen[seen <= params.max_pixels]
        band = (int(seen.min()), int(seen.max())) if seen.size else (0, 0)
        return DetectionSetup(
            params, self.choices, self.kind, len(self.frames), lv, band, tuple(self.notes)
        )

    def _nothing_bright(self, probe: float) -> DetectionSetup:
        self.notes.append(f"no bright spot {probe:.3g} grey levels above the background")
        for name in DERIVED:
            default = getattr(DetectionParams(), name)
            self.choose(name, default, "nothing bright in the surveyed frames: default")
        params = DetectionParams.from_layers(self.values, self.given)
        return DetectionSetup(
            params, self.choices, self.kind, len(self.frames), self.levels, notes=tuple(self.notes)
        )

    def _threshold(self, markers: Groups) -> None:
        """Threshold and background mode from the contrast of the faint markers."""
        lv = self.levels
        faint = float(np.percentile(markers.peak, 5)) if len(markers) else 40.0
        floor = max(5.0 * lv.noise, 3.0 * lv.unit)
        excess = float(np.clip(THRESHOLD_FRACTION * faint, floor, max(floor, 0.6 * faint)))
        why = (
            f"{THRESHOLD_FRACTION:.0%} of the faint markers' contrast ({faint:.0f} above "
            f"background), at least 5 noise deviations ({lv.noise:.1f})"
        )
        if floor > 0.5 * faint:
            self.notes.append(
                f"faint markers ({faint:.0f} grey levels) are near the noise ({lv.noise:.1f})"
            )
        extent = np.maximum(markers.width, markers.height)
        size = float(np.percentile(extent, 95)) if len(markers) else 8.0
        tile, share = self._tile(size, excess)
        fine = share > STRUCTURE_SHARE_MAX
        local = lv.unevenness > 0.5 * excess or fine
        lit = f"lit at the markers' scale over {share:.1%} of the image"
        tile_why = f"background even (spread {lv.unevenness:.0f} grey levels): one level"
        if fine:
            tile_why = f"local, tiles of 2 marker diameters: the background is {lit} (walls, edges)"
        elif local:
            tile_why = f"background uneven by {lv.unevenness:.0f} grey levels, {lit}: local, "
            tile_why += "tiles of 4 marker diameters"
        # a threshold given keeps the terms the derived one would be in (above the local
        # background here), so that copying the printed value back gives the same blobs
        self.choose("background_tile_px", tile if local else 0, tile_why)
        self.choose(
            "threshold",
            round(excess, 1) if local else round(lv.background + excess, 1),
            why + (" over the local background" if local else ""),
        )

    def _tile(self, size: float, excess: float) -> tuple[int, float]:
        """Background tile (px) for markers ``size`` px wide, and the share of the image
        lit at the markers' scale (:func:`~kisscal.detect.survey.structure_share`).

        Four marker diameters keep the markers out of the tile median even where they
        crowd. Where the background itself is lit at a finer scale (walls, edges, bands
        of a real scene, between a marker and such a tile) over more than
        :data:`STRUCTURE_SHARE_MAX` of the image, tiles of two diameters follow it; a
        smooth glow keeps the larger tiles, which are steadier.
        """
        limit = min(self.frames[0].shape) // 2
        tile = int(min(max(32, 4 * math.ceil(size)), limit))
        small = int(min(max(MIN_TILE_PX, 2 * math.ceil(size)), tile))
        if small >= tile:
            return tile, 0.0
        noise_factor = float(self._partial_params().noise_factor)
        share = structure_share(self.frames, tile, small, excess, noise_factor)
        return (small if share > STRUCTURE_SHARE_MAX else tile), share

    def _partial_params(self) -> DetectionParams:
        return DetectionParams.from_layers(self.values, self.given)

    def _final_groups(self) -> Groups:
        """Groups at the chosen threshold (sizes depend on it)."""
        p = self._partial_params()
        tile = p.background_tile_px or max(32, min(self.frames[0].shape) // 8)
        if p.background_tile_px:
            excess = p.threshold
        else:
            excess = max(p.threshold - self.levels.background, self.levels.unit)
        return survey_frames(self.frames, excess, tile)

    def _aspect(self, spots: Groups) -> None:
        if self.known_aspect is not None:
            self.choose("pixel_aspect", *self.known_aspect)
            return
        value, why = measure_pixel_aspect(spots)
        self.choose("pixel_aspect", value, why)

    def _shape_tests(self, spots: Groups) -> None:
        """Whether a group's shape alone may split it (overlap and long/wide tests).

        Those tests take a group that is not round for two markers. They hold where single
        markers image as round spots; where isolated spots (single objects for sure) are
        often not round (irregular particles, specks, comet tails), or too few are seen to
        tell, shape says nothing about how many objects a group holds, and only a neck
        between them (the touching test) may split it.
        """
        p = self._partial_params()
        ok = spots.inside & (spots.pixels >= p.long_wide_min_pixels)
        ok &= (spots.var_x > 0) & (spots.var_y > 0)
        if p.max_pixels is not None:
            ok &= spots.pixels <= p.max_pixels
        if ok.sum() < MIN_SPOTS_FOR_ASPECT:
            why = (
                f"only {int(ok.sum())} isolated spots: too few to show that single markers "
                "image as round spots"
            )
            self.choose("split_overlaps", False, why)
            self.choose("split_long_wide", False, why)
            return
        why = shapes_off_reason(spots.var_x[ok], spots.var_y[ok], spots.cov_xy[ok], p)
        if why is None:
            why = cut_singles_reason(self.frames, spots.take(ok), p)
        if why is None:
            return
        self.choose("split_overlaps", False, why)
        self.choose("split_long_wide", False, why)

    def _size_limits(self, groups: Groups, markers: NDArray[np.bool_], top: float | None) -> None:
        """Upper size limits between the markers and the oversized blobs, the detach
        kernel and the lower limit."""
        m = groups.take(markers)
        if not len(m):
            for name in ("max_pixels", "max_width_px", "max_height_px", "detach_kernel_px"):
                self.choose(name, None, "no marker-like blob seen: no upper limit")
            self.choose("min_pixels", DetectionParams().min_pixels, "no marker-like blob seen")
            return
        big = groups.take(~markers & (groups.pixels > m.pixels.max()))
        # single markers (isolated, filled): touching pairs are split before the limits;
        # extents: round markers' from their area; a target's dots seen obliquely their own
        single = m.take((m.isolation > 3.0) & (m.fill > 0.6))
        pixels = largest_size((single if len(single) >= 5 else m).pixels)
        if top is not None:  # the objects' crowd reaches further than most singles
            pixels = max(pixels, min(top, float(m.pixels.max())))
        aspect = float(self._partial_params().pixel_aspect)
        width, height = marker_extent(m, pixels, aspect, target=self.kind == "grid")
        size = {"pixels": pixels, "width": width, "height": height}
        self._upper_limits(size, big)
        self._detach_kernel(size, big)
        smallest = float(np.percentile(m.pixels, 1)) if len(m) >= 50 else float(m.pixels.min())
        self.choose(
            "min_pixels",
            max(3, int(0.3 * smallest)),
            f"under a third of the smallest markers ({smallest:.0f} px): pieces, not markers",
        )

    def _upper_limits(self, size: dict[str, float], big: Groups) -> None:
        headroom = SIZE_HEADROOM if self.kind == "markers" else 1.5
        why = f"largest markers {size['pixels']:.0f} px ({size['width']:.0f} x " + (
            f"{size['height']:.0f}); "
            + (f"smallest oversized blob {big.pixels.min()} px" if len(big) else "none oversized")
        )
        for name, key, scale, pad in (
            ("max_pixels", "pixels", headroom, 0),
            ("max_width_px", "width", math.sqrt(headroom), 1),
            ("max_height_px", "height", math.sqrt(headroom), 1),
        ):
            limit = math.ceil(size[key] * scale) + pad
            above = getattr(big, key).min() if len(big) else math.inf
            # a gap between the markers and the oversized: the limit between them; blobs
            # of every size up from the markers (glare, a continuum): the headroom
            if len(big) and above >= OVERSIZE_GAP * size[key]:
                limit = min(limit, math.floor(math.sqrt(size[key] * above)))
            self.choose(name, int(max(limit, math.ceil(size[key]) + 1)), why)

    def _detach_kernel(self, size: dict[str, float], big: Groups) -> None:
        kw = odd_size(1.2 * size["width"] + 1)
        kh = odd_size(1.2 * size["height"] + 1)
        fits = not len(big) or (kw < big.width.min() and kh < big.height.min())
        self.choose(
            "detach_kernel_px",
            (kw, kh) if fits else None,
            "a fifth larger than the largest markers"
            if fits
            else "oversized blobs are not larger than the kernel: no detaching",
        )

    def _margins(self) -> None:
        """Centroid margins from the markers' rims (not LED rings' flare); on uneven
        backgrounds (halos, ghosts, glow) a band-pass centroid about a marker wide."""
        p = self._partial_params()
        local = p.background_tile_px > 0 and self.marker_width > 0
        side = odd_size(HIGHPASS_SIDE * self.marker_width) if local else 0
        why = "uneven background: band-pass of 0.9 largest marker widths" if local else ""
        self.choose("centroid_highpass_px", side, why or "even background: plain weights")
        reach = []
        for image in self.frames:
            white, background = threshold_image(image, p)
            markers = marker_mask(white, p.max_pixels)
            reach.append(rim_reach_px(image, markers, background, self._rim_floor()))
        reach = np.array(reach)
        mx, my = (int(np.clip(np.median(reach[:, k]), 1, 8)) for k in (0, 1))
        why = "how far the blurred rim reaches beyond the white pixels"
        self.choose("centroid_margin_x_px", mx, why)
        self.choose("centroid_margin_y_px", my, why)

    def _rim_floor(self) -> float:
        # a ring fainter than twice the noise adds more noise to a centroid than light
        return max(2.0 * self.levels.noise, 0.5 * self.levels.unit)
