"""The result of blob detection: a long-format table over numpy arrays, one row per group."""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

# Flags name the advanced-analysis tests (Shafiq et al. 2001, section 2.3) that touched a blob; they
# are bits so a blob can carry several (e.g. split_wide and too_small).
MERGED = 1
SPLIT_UL = 2
SPLIT_UR = 4
SPLIT_WIDE = 8
SPLIT_LONG = 16
TOO_LARGE = 32
TOO_SMALL = 64
DETACHED = 128
SPLIT_TOUCHING = 256
FLAG_NAMES: dict[int, str] = {
    MERGED: "merged",
    SPLIT_UL: "split_ul",
    SPLIT_UR: "split_ur",
    SPLIT_WIDE: "split_wide",
    SPLIT_LONG: "split_long",
    TOO_LARGE: "too_large",
    TOO_SMALL: "too_small",
    DETACHED: "detached",
    SPLIT_TOUCHING: "split_touching",
}
INVALID_FLAGS = TOO_LARGE | TOO_SMALL


def flag_string(flags: int) -> str:
    """Return ``flags`` as names joined by ``|`` (e.g. ``split_ul|too_large``); ``""`` if none."""
    return "|".join(name for bit, name in FLAG_NAMES.items() if flags & bit)


def parse_flags(text: str) -> int:
    """Inverse of :func:`flag_string`; raises ``ValueError`` on an unknown name."""
    by_name = {name: bit for bit, name in FLAG_NAMES.items()}
    value = 0
    for name in filter(None, (part.strip() for part in text.split("|"))):
        if name not in by_name:
            raise ValueError(f"unknown blob flag {name!r}")
        value |= by_name[name]
    return value


@dataclass(frozen=True)
class Blobs:
    """Detected groups of one image (Shafiq et al. 2001, section 2), one entry per group.

    Attributes
    ----------
    x_px, y_px : ndarray of float
        Reported centroid (pixels, origin at the centre of the top-left pixel): the
        intensity-weighted centroid when a grayscale image was given and
        ``DetectionParams.weighted_centroid`` is on, else the binary centroid.
    x_binary_px, y_binary_px : ndarray of float
        Plain pixel centroid of the white pixels (equation 2).
    pixels : ndarray of int
        White pixels in the group (equation 5).
    w_px, h_px : ndarray of int
        Width and height of the bounding rectangle in pixels (columns and rows covered).
    valid : ndarray of bool
        False for groups marked invalid by the size limits (section 2.3.4).
    flags : ndarray of int
        Bit set of the tests that touched the group, see :data:`FLAG_NAMES`.
    """

    x_px: NDArray[np.float64]
    y_px: NDArray[np.float64]
    x_binary_px: NDArray[np.float64]
    y_binary_px: NDArray[np.float64]
    pixels: NDArray[np.int64]
    w_px: NDArray[np.int64]
    h_px: NDArray[np.int64]
    valid: NDArray[np.bool_]
    flags: NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.x_px.shape[0])

    @classmethod
    def empty(cls) -> Blobs:
        """A table with no rows."""
        f = np.zeros(0, dtype=float)
        i = np.zeros(0, dtype=np.int64)
        return cls(f, f, f, f, i, i, i, np.zeros(0, dtype=bool), i)

    def select(self, keep: NDArray[np.bool_] | NDArray[np.int64]) -> Blobs:
        """Rows chosen by a boolean mask or an index array."""
        return Blobs(**{f.name: getattr(self, f.name)[keep] for f in fields(self)})

    def valid_only(self) -> Blobs:
        """The valid rows (what the reconstruction and calibration stages use)."""
        return self.select(self.valid)

    @property
    def xy_px(self) -> NDArray[np.float64]:
        """Reported centroids as an ``(n, 2)`` array."""
        return np.column_stack([self.x_px, self.y_px])
