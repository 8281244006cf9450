"""Every parameter of the blob detection front end, in one frozen dataclass.

Shafiq, Tümer & Güler (2001, section 3) stress that the thresholds must be tuned to the
equipment. The defaults here assume nothing of a camera (square pixels, no size limits);
:mod:`kisscal.detect.configure` derives the camera-dependent ones (threshold, background,
pixel aspect, size limits, kernels) from a sample of a camera's own images, and every one
can be given in ``session.toml`` ``[detection]``.

References
----------
Crocker, J. C., & Grier, D. G. (1996). Methods of digital video microscopy for colloidal
studies. Journal of Colloid and Interface Science, 179(1), 298-310.
Shafiq, M. S., Tümer, S. T., & Güler, H. C. (2001). Marker detection and trajectory
generation algorithms for a multicamera based gait analysis system. Mechatronics, 11(4),
409-437.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from kisscal.params import Params, param


@dataclass(frozen=True)
class DetectionParams(Params):
    """Parameters of blob detection (Shafiq et al. 2001, section 2), each with its unit.

    Attributes
    ----------
    polarity : {"auto", "bright", "dark"}
        Which way round the objects are: "bright" spots on a darker surround (IR markers,
        lit particles, back-lit targets) or "dark" spots on a bright background (black
        dots printed on a white plate), which are inverted before everything else, so
        that every grey-level setting below reads the inverted image. "auto" decides per
        image from its grey levels (:mod:`kisscal.detect.polarity`); the derived settings
        of a camera hold the decision.
    threshold : float
        Grey level (8-bit scale: 16-bit images are read on it) at or above which a pixel is
        white; with ``background_tile_px`` > 0, the grey levels a pixel must stand above its
        local background. Derived per camera from the images (:mod:`kisscal.detect.configure`):
        about a quarter of the faintest markers' contrast, so that small far markers stay at
        least two rows tall for the one-pixel-high noise rule (section 2.2), and well above
        the sensor noise. Ignored for boolean (already thresholded) images.
    background_tile_px : int
        0: the background is one grey level per image (the median of a sparse sample, or
        ``background``). Otherwise the background is local, the median over tiles of about
        this many pixels (:func:`kisscal.detect.background.background_map`), for images whose
        surround is not uniformly dark; both the white test and the weighted centroids use it.
    noise_factor : float
        With a local background, a pixel must also stand this many local noise deviations
        above it (:func:`kisscal.detect.background.local_noise_map`): bright surfaces are
        noisier than dark ones. 0 turns the local noise test off.
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
        test; not in Shafiq et al. 2001. Only groups whose shape or size is not that of one marker
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
        Width / height in pixels of the image of a round marker (pixel height / pixel width):
        1 for square pixels, about 1.94 for 4:3 frames of 752 x 582 pixels scanned as
        291-line fields (KISS). Derived per camera from the shape of its isolated markers.
    detach_from_large : bool
        Separate markers touching an oversized blob (LED ring) from it before the size
        limits; not in Shafiq et al. 2001 (there such a marker is lost with the invalid blob).
    detach_kernel_px : (int, int) or None
        Width and height (pixels, odd) of the elliptical opening that keeps an LED ring
        and removes markers: larger than a marker image, smaller than an LED ring. Derived
        with the size limits; None: no detaching.
    detach_appendages : bool
        Cut thin pieces (a streak, a fibre, a speck on a thin neck) off a thick spot they
        touch, by a morphological opening of the group (:mod:`kisscal.detect.appendage`),
        so that a target dot's centroid weighs only the dot; not in Shafiq et al. 2001.
    detach_cores : bool
        Separate the bright cores of marker size from an oversized group (a marker in a
        glare halo, on a lit wall, with a comet tail or a dim ghost): within the group,
        pixels above half-way from its median level to its peak
        (:mod:`kisscal.detect.cores`); not in Shafiq et al. 2001.
    detach_min_pixels : int
        Least white pixels of a piece sticking out of an oversized blob to be a marker.
    apply_size_limits : bool
        Section 2.3.4 switch: oversized and undersized groups are marked invalid (kept in
        the table with ``too_large`` / ``too_small``).
    max_pixels : int or None
        A group with more white pixels is too large (LED rings of facing cameras,
        reflections); None: no upper limit. Derived per camera and image kind from the
        size distribution of its blobs (on the KISS-like rig, 25 mm markers at 2.5-7 m give
        13-40 white pixels and the LED rings 128-176: the limit sits between).
    max_width_px, max_height_px : int or None
        A group wider or higher than this is too large; None: no limit.
    split_max_markers : int
        A group is split into markers (overlap, long/wide, touching tests) only when it
        could hold at most this many markers, ``pixels <= split_max_markers * max_pixels``:
        larger groups are bright regions (a lit surface, a reflection), not marker
        clusters, and are left whole for the size limits. Long and wide groups are cut into
        at most this many parts.
    min_pixels : int
        A group with fewer white pixels is too small.
    weighted_centroid : bool
        Report the intensity-weighted centroid (DESIGN.md) when the image is grayscale; the
        binary pixel centroid (equation 2) is always computed as well.
    centroid_margin_x_px, centroid_margin_y_px : int
        The weighted centroid sums over the group's bounding rectangle grown by these many
        pixels, so the blurred rim below the threshold is included.
    centroid_highpass_px : int
        0: the weighted centroid weighs ``I - background``. Otherwise it weighs how far each
        pixel stands above the mean grey level of the square of this side around it (zero
        where below), as particle trackers' band-pass centroids do (Crocker & Grier 1996):
        a dim halo, a reflected ghost crescent or a glow wider than the spot then adds
        little weight and the centroid stays on the spot's bright core. Derived with the
        size limits for uneven (locally thresholded) backgrounds, about 1.5 marker
        diameters.
    background : float or None
        Background grey level subtracted before weighting (global background only);
        ``None`` estimates it per image as the median of a sparse pixel sample.
    route : {"blobs", "peaks"}
        "blobs": the run-length grouping and tests above (markers, dots). "peaks": particle
        images as particle-tracking velocimetry finds them (Maas et al. 1993;
        :mod:`kisscal.detect.peaks`): the image less its ``peak_highpass_px`` box mean,
        regions above ``threshold`` there grown from their peaks (``peak_step``), regions
        larger than ``max_pixels`` cut at higher levels while too large,
        weighted centroids. Derived per camera: chosen
        for frames of many small spots and no marker-sized blobs
        (:mod:`kisscal.detect.route`).
    peak_highpass_px : int
        Side (odd) of the box whose mean the "peaks" route subtracts.
    peak_min_extent_px : int
        "peaks" route: a region narrower or lower than this is too small.
    peak_min_sum_grey : float
        "peaks" route: a region whose high-passed grey levels sum to less is too small.
    peak_step : float
        "peaks" route: a particle image grows from its peak while no step enters a pixel
        (or a pixel beside it) more than this above the one it leaves, so that a bright
        particle beside a faint one is an image of its own (Maas 1992's discontinuity;
        OpenPTV's experiments use 100).
    peak_min_spots : int
        Route choice (:mod:`kisscal.detect.route`): least spots of the marker population
        per frame for particle frames.
    peak_min_density : float
        Route choice: least such spots per megapixel per frame.
    peak_small_spot_px : float
        Route choice: largest median white pixels of those spots (particle images are a
        few pixels wide).
    peak_size_span : float
        Route choice: least ratio of the 90th to the 10th percentile of the spots' sizes
        (particle images have every size, the dots of a target or grid one size).
    peak_noise_factor : float
        "peaks" route's derived ``threshold``, in robust deviations (1.4826 MAD) of the
        frames less their ``peak_highpass_px`` box mean.
    peak_sum_factor : float
        "peaks" route's derived ``peak_min_sum_grey``, in thresholds (four pixels three
        thresholds up; OpenPTV's cavity experiment asks 150 at thresholds of 9 and 11).
    """

    section: ClassVar[str] = "detection"

    polarity: str = param("auto", choices=("auto", "bright", "dark"))
    threshold: float = param(40.0, unit="grey levels", ge=0)
    background_tile_px: int = param(0, unit="px", ge=0)
    noise_factor: float = param(5.0, ge=0)
    closeness_x_px: float = param(0.0, unit="px", ge=0)
    closeness_rows: int = param(1, unit="lines", ge=1)
    remove_lonely: bool = param(True)
    remove_one_pixel_wide: bool = param(True)
    remove_one_pixel_high: bool = param(True)
    noise_min_width_px: int = param(2, unit="px", ge=0)
    noise_min_height_px: int = param(2, unit="px", ge=0)
    merge_submarkers: bool = param(True)
    submarker_max_pixels: int = param(8, unit="px", ge=0)
    submarker_max_rows: int = param(2, unit="lines", ge=1)
    submarker_overlap: float = param(0.5, ge=0, le=1)
    submarker_margin_px: int = param(1, unit="px", ge=0)
    split_touching: bool = param(True)
    touching_separation: float = param(1.2, ge=0)
    split_overlaps: bool = param(True)
    overlap_ratio_max: float = param(0.6, ge=0, le=1)
    overlap_shift_px: float = param(3.0, unit="px", ge=0)
    overlap_min_elongation: float = param(1.3, ge=1)
    overlap_angle_deg: float = param(20.0, unit="deg", ge=0, le=45)
    split_long_wide: bool = param(True)
    min_ratio: float = param(0.78, gt=0, lt=1)
    max_ratio: float = param(1.3, gt=1)
    long_wide_min_pixels: int = param(16, unit="px", ge=0)
    split_max_markers: int = param(4, ge=2)
    growth_px: float = param(0.35, unit="px", ge=0)
    growth_min_groups: int = param(5, ge=0)
    split_min_extent: float = param(1.25, ge=0)
    edge_growth_px: float = param(1.0, unit="px", ge=0)
    pixel_aspect: float = param(1.0, gt=0)
    detach_from_large: bool = param(True)
    detach_kernel_px: tuple[int, int] | None = param(None, unit="px", gt=0, odd=True)
    detach_appendages: bool = param(True)
    detach_cores: bool = param(True)
    detach_min_pixels: int = param(8, unit="px", ge=0)
    apply_size_limits: bool = param(True)
    max_pixels: int | None = param(None, unit="px", gt=0)
    max_width_px: int | None = param(None, unit="px", gt=0)
    max_height_px: int | None = param(None, unit="px", gt=0)
    min_pixels: int = param(3, unit="px", ge=0)
    weighted_centroid: bool = param(True)
    centroid_margin_x_px: int = param(3, unit="px", ge=0)
    centroid_margin_y_px: int = param(3, unit="px", ge=0)
    centroid_highpass_px: int = param(0, unit="px", ge=0)
    background: float | None = param(None, unit="grey levels")
    route: str = param("blobs", choices=("blobs", "peaks"))
    peak_highpass_px: int = param(51, unit="px", ge=3, odd=True)
    peak_min_extent_px: int = param(2, unit="px", ge=1)
    peak_min_sum_grey: float = param(0.0, unit="grey levels", ge=0)
    peak_step: float = param(100.0, unit="grey levels", gt=0)
    peak_min_spots: int = param(200, ge=1)
    peak_min_density: float = param(1000.0, unit="per megapixel", ge=0)
    peak_small_spot_px: float = param(16.0, unit="px", gt=0)
    peak_size_span: float = param(4.0, ge=1)
    peak_noise_factor: float = param(2.5, gt=0)
    peak_sum_factor: float = param(12.0, ge=0)

    def without_advanced_analysis(self) -> DetectionParams:
        """These parameters with every section 2.3 test (and kisscal's additions) off."""
        return self.replace(
            merge_submarkers=False,
            detach_from_large=False,
            detach_appendages=False,
            detach_cores=False,
            split_touching=False,
            split_overlaps=False,
            split_long_wide=False,
            apply_size_limits=False,
        )
