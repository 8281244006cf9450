"""Blob detection: run-length pixel grouping, noise removal, merge/split tests, centroids.

The method is Shafiq, Tümer & Güler 2001 (seeds/003, section 2). Call
:func:`detect_blobs` on one image or :func:`detect_sequence` on many; tune with
:class:`DetectionParams`.
"""

from kisscal.detect.blobs import FLAG_NAMES, Blobs, flag_string, parse_flags
from kisscal.detect.params import DetectionParams
from kisscal.detect.pipeline import check_image, detect_blobs, detect_sequence

__all__ = [
    "FLAG_NAMES",
    "Blobs",
    "DetectionParams",
    "check_image",
    "detect_blobs",
    "detect_sequence",
    "flag_string",
    "parse_flags",
]
