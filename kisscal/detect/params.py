"""Every default of the blob detection front end, in one frozen dataclass.

The defaults are chosen for KISS-like 752 x 291 interlaced fields, 8-bit, where a round
marker images about 1.9 times wider than tall (non-square pixels; see ``pixel_aspect``).
Shafiq, Tümer & Güler 2001 (seeds/003, section 3) stress that the thresholds must be tuned
to the equipment; every one can be overridden from ``session.toml`` ``[detection]``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from kisscal.errors import KisscalError


@dataclass(frozen=True)
class DetectionParams:
    """Parameters of blob detection (seeds/003 section 2), each with its unit.

    Attributes
    ----------
    threshold : float
        Grey level (image units) at or above which a pixel is white. Low on purpose: markers
        peak near saturation over a background of a few grey levels, and a low threshold
        keeps small far markers at least two rows tall so the one-pixel-high noise rule
        (section 2.2) cannot remove them. Ignored for boolean (already thresholded) images.
    closeness_x_px : float
        Section 2.1 grouping: a run joins a group when its mid-point lies within the sum of
        the two runs' half-lengths plus this many pixels of a run of that group in a
        neighbouring scan line. 0 joins runs that touch (8-connected runs).
    closeness_rows : int
        Section 2.1 grouping: how many scan lines apart two runs may be and still be
        compared (1 = adjacent lines only).
    remove_lonely : bool
        Section 2.2: remove single-pixel groups.
    remove_one_pixel_wide : bool
        Section 2.2: remove groups one pixel wide (vertical streaks).
    remove_one_pixel_high : bool
        Section 2.2: remove groups one scan line high (horizontal streaks).
    noise_min_width_px, noise_min_height_px : int
        Section 2.2, former method: a group narrower than ``noise_min_width_px`` *and* lower
        than ``noise_min_height_px`` is noise.
    merge_submarkers : bool
        Section 2.3.1 switch.
    submarker_max_pixels : int
        A group is a sub-marker candidate when it has at most this many white pixels and at
        most ``submarker_max_rows`` rows.
    submarker_max_rows : int
        Row limit of a sub-marker (the paper uses two).
    submarker_overlap : float
        Fraction (0-1) of the sub-marker's bounding rectangle that must lie within the
        (margin-grown) bounding rectangle of the larger group it is merged into.
    submarker_margin_px : int
        Pixels by which the larger group's bounding rectangle is grown for that test.
    split_touching : bool
        Split groups whose distance transform has several peaks (touching markers, e.g.
        three foot markers in a cluster) into one group per peak, before the overlap
        test; not in seeds/003. Only groups whose shape or size is not that of one marker
        are examined.
    touching_separation : float
        Two distance-transform peaks are two markers when they are further apart than
        this many times the larger one's height (marker radius).
    split_overlaps : bool
        Section 2.3.2 switch (ul / ur overlapped pairs, equation 6).
    overlap_ratio_max : float
        WhitePixels / TotalPixels (equations 4, 5) below which a group is tested for overlap.
        A single elliptic spot fills about pi/4 = 0.785 of its bounding rectangle.
    overlap_shift_px : float
        Equation (6), second condition: minimum horizontal shift (pixels) between the
        mid-points of the top and bottom rows (the paper uses 3).
    overlap_min_elongation : float
        Major / minor axis ratio (round units, from the second moments of the group's white
        pixels) at or above which a diagonally elongated group is an overlapped pair even
        when equation (6) misses it (small spots have too few rows for it). Two round
        markers one radius apart give about 1.4.
    overlap_angle_deg : float
        How far (degrees, round units) the major axis must be from both image axes for
        that moment test; closer to an axis the long/wide test is the one that applies.
    split_long_wide : bool
        Section 2.3.3 switch.
    min_ratio, max_ratio : float
        minR and maxR of section 2.3.3, applied to the aspect-corrected height-to-width
        ratio of the spot's second moments over its white pixels (about 1 for a round
        marker, 0.95-1.4 for small ones with blur and blooming): below ``min_ratio`` a group
        is wide, above ``max_ratio`` long. Two markers one radius or more apart give at
        most about 0.8-0.9 (side by side) or at least 1.5 (one above the other).
    long_wide_min_pixels : int
        Groups with fewer white pixels are not tested for overlap, long or wide: their
        shape is a handful of pixels and says nothing about how many markers they hold.
    growth_px : float
        Spread (standard deviation, pixels) that blur, blooming and thresholding add to
        every spot in x and y alike; removed from the spot moments before the shape tests
        (:mod:`kisscal.detect.shape`). Estimated per image from its marker-sized groups;
        this value is used when an image has fewer than ``growth_min_groups`` of them.
    growth_min_groups : int
        Least number of marker-sized groups for the per-image growth estimate.
    split_min_extent : float
        A small long or wide group (fewer than 1.5 ``long_wide_min_pixels``) is cut only
        when it is at least this many marker diameters long along the cut (two markers
        one radius apart measure about 1.4): the moment ratio of a small single spot is
        noisy, its extent less so.
    edge_growth_px : float
        How much wider and taller (pixels) the thresholded image of a marker is than its
        outline: blur and blooming add about the same in both directions, independent of
        the pixel aspect. Used to estimate a marker's diameter when splitting.
    pixel_aspect : float
        Width / height in pixels of the image of a round marker (pixel height / pixel width);
        1.94 for 4:3 frames of 752 x 582 pixels scanned as 291-line fields.
    detach_from_large : bool
        Separate markers touching an oversized blob (LED ring) from it before the size
        limits; not in seeds/003 (there such a marker is lost with the invalid blob).
    detach_kernel_px : (int, int)
        Width and height (pixels, odd) of the elliptical opening that keeps an LED ring
        and removes markers: larger than a marker image, smaller than an LED ring.
    detach_min_pixels : int
        Least white pixels of a piece sticking out of an oversized blob to be a marker.
    apply_size_limits : bool
        Section 2.3.4 switch: oversized and undersized groups are marked invalid (kept in
        the table with ``too_large`` / ``too_small``), never split.
    max_pixels : int
        A group with more white pixels is too large (LED rings of facing cameras). On the
        KISS-like rig, 25 mm markers at 2.5-7 m give 13-40 white pixels (at most 9 x 6)
        and the LED rings 128-176 (at least 15 x 10): the limits sit between.
    max_width_px, max_height_px : int
        A group wider or higher than this is too large.
    min_pixels : int
        A group with fewer white pixels is too small.
    weighted_centroid : bool
        Report the intensity-weighted centroid (DESIGN.md) when the image is grayscale; the
        binary pixel centroid (equation 2) is always computed as well.
    centroid_margin_x_px, centroid_margin_y_px : int
        The weighted centroid sums over the group's bounding rectangle grown by these many
        pixels, so the blurred rim below the threshold is included.
    background : float | None
        Background grey level subtracted before weighting; ``None`` estimates it per image
        as the median of a sparse pixel sample.
    """

    threshold: float = 40.0
    closeness_x_px: float = 0.0
    closeness_rows: int = 1
    remove_lonely: bool = True
    remove_one_pixel_wide: bool = True
    remove_one_pixel_high: bool = True
    noise_min_width_px: int = 2
    noise_min_height_px: int = 2
    merge_submarkers: bool = True
    submarker_max_pixels: int = 8
    submarker_max_rows: int = 2
    submarker_overlap: float = 0.5
    submarker_margin_px: int = 1
    split_touching: bool = True
    touching_separation: float = 1.2
    split_overlaps: bool = True
    overlap_ratio_max: float = 0.6
    overlap_shift_px: float = 3.0
    overlap_min_elongation: float = 1.3
    overlap_angle_deg: float = 20.0
    split_long_wide: bool = True
    min_ratio: float = 0.78
    max_ratio: float = 1.3
    long_wide_min_pixels: int = 16
    growth_px: float = 0.35
    growth_min_groups: int = 5
    split_min_extent: float = 1.25
    edge_growth_px: float = 1.0
    pixel_aspect: float = 1.94
    detach_from_large: bool = True
    detach_kernel_px: tuple[int, int] = (11, 7)
    detach_min_pixels: int = 8
    apply_size_limits: bool = True
    max_pixels: int = 80
    max_width_px: int = 14
    max_height_px: int = 9
    min_pixels: int = 3
    weighted_centroid: bool = True
    centroid_margin_x_px: int = 3
    centroid_margin_y_px: int = 2
    background: float | None = None

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            kind = str(f.type)
            if kind == "bool":
                ok = isinstance(value, bool | np.bool_)
            elif kind == "int":
                ok = isinstance(value, int | np.integer) and not isinstance(value, bool)
            elif kind.startswith("float"):
                ok = (value is None and "None" in kind) or (
                    isinstance(value, int | float | np.integer | np.floating)
                    and not isinstance(value, bool)
                )
            else:  # the opening kernel: two odd positive integers
                ok = (
                    isinstance(value, tuple)
                    and len(value) == 2
                    and all(isinstance(v, int) and v > 0 and v % 2 == 1 for v in value)
                )
            if not ok:
                raise KisscalError(
                    f"detection: {f.name} must be {kind.replace('tuple[int, int]', 'two odd ints')}"
                    f", got {value!r}"
                )
        positive = ("closeness_rows", "pixel_aspect", "max_pixels", "max_width_px")
        for name in (*positive, "max_height_px", "submarker_max_rows"):
            if not getattr(self, name) > 0:
                raise KisscalError(f"detection: {name} must be > 0, got {getattr(self, name)}")
        for name in (
            "closeness_x_px",
            "submarker_max_pixels",
            "overlap_shift_px",
            "overlap_angle_deg",
            "edge_growth_px",
            "growth_px",
            "growth_min_groups",
            "touching_separation",
            "split_min_extent",
            "min_pixels",
            "long_wide_min_pixels",
            "centroid_margin_x_px",
            "centroid_margin_y_px",
            "submarker_margin_px",
        ):
            if getattr(self, name) < 0:
                raise KisscalError(f"detection: {name} must be >= 0, got {getattr(self, name)}")
        if not 0 < self.min_ratio < 1 < self.max_ratio:
            raise KisscalError(
                f"detection: need 0 < min_ratio < 1 < max_ratio, got {self.min_ratio}, "
                f"{self.max_ratio}"
            )
        for name in ("submarker_overlap", "overlap_ratio_max"):
            if not 0 <= getattr(self, name) <= 1:
                raise KisscalError(f"detection: {name} must be in [0, 1]")

    def replace(self, **changes: object) -> DetectionParams:
        """Return a copy with ``changes``; unknown names raise :class:`KisscalError`."""
        known = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - known)
        if unknown:
            raise KisscalError(
                f"detection: unknown parameter(s) {', '.join(unknown)}; known: "
                + ", ".join(sorted(known))
            )
        return dataclasses.replace(self, **changes)

    def without_advanced_analysis(self) -> DetectionParams:
        """These parameters with every section 2.3 test (and kisscal's additions) off."""
        return self.replace(
            merge_submarkers=False,
            detach_from_large=False,
            split_touching=False,
            split_overlaps=False,
            split_long_wide=False,
            apply_size_limits=False,
        )
