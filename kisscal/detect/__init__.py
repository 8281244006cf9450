"""Blob detection: run-length pixel grouping, noise removal, merge/split tests, centroids.

The method is Shafiq, Tümer & Güler (2001, section 2). Call
:func:`detect_blobs` on one image or :func:`detect_sequence` on many; tune with
:class:`DetectionParams`.

Modules: :mod:`~kisscal.detect.scan` (run-length scan, mid-point grouping),
:mod:`~kisscal.detect.groups` (bounding rectangles, equations 1-5),
:mod:`~kisscal.detect.noise` (section 2.2), :mod:`~kisscal.detect.advanced` (section 2.3
and the LED separation), :mod:`~kisscal.detect.touching` (touching markers),
:mod:`~kisscal.detect.shape` (moment shape tests), :mod:`~kisscal.detect.centroid`
(weighted centroids), :mod:`~kisscal.detect.pipeline` (the whole analysis of one image),
:mod:`~kisscal.detect.sequence` (many images in parallel processes).
"""

from kisscal.detect.blobs import FLAG_NAMES, Blobs, flag_string, parse_flags
from kisscal.detect.params import DetectionParams
from kisscal.detect.pipeline import check_image, detect_blobs
from kisscal.detect.sequence import ImageJob, detect_jobs, detect_sequence

__all__ = [
    "FLAG_NAMES",
    "Blobs",
    "DetectionParams",
    "ImageJob",
    "check_image",
    "detect_blobs",
    "detect_jobs",
    "detect_sequence",
    "flag_string",
    "parse_flags",
]
