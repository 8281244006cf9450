"""Marker sets kisscal ships: names, rigid segments, mirror pairs and a standing template.

A session picks one by name (``[markers] set = "plug-in-gait-lower"``); the data live in
``kisscal/markersets/data/*.toml``, written by ``tests/markersets/derive_markersets.py`` from
anthropometric proportions (Winter 2009; Bell et al. 1990).

Example
-------
>>> from kisscal.markersets import marker_set
>>> marker_set("kiss", names=None).names[:3]
('SACR', 'RASI', 'LASI')
"""

from kisscal.markersets.loader import available_marker_sets, marker_set
from kisscal.markersets.model import MarkerSet

__all__ = ["MarkerSet", "available_marker_sets", "marker_set"]
