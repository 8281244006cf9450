"""Known-target calibration: a calibration object matched automatically from clicked seeds.

Typical use for one camera (arrays only; :mod:`kisscal.session.routes.target` runs it
for a session)::

    dots = find_target_dots(image, seeds_uv, TargetParams())
    match = match_target(target_xyz, seeds_uv, seeds_xyz, dots, size_px, "cam1")
    match.camera, match.dot, match.visible

Modules: :mod:`~kisscal.target.dots` (dots under uneven light),
:mod:`~kisscal.target.seeds` (which rows of a seeds file are clicks, how many a camera
needs), :mod:`~kisscal.target.match` (first cameras from the seeds, matching rounds) and
:mod:`~kisscal.target.resect` (a pinhole resection from four or more points, and the terms
beyond it that the held-out points ask for).
"""

from kisscal.target.dots import find_dots, find_target_dots
from kisscal.target.match import TargetMatch, fit_camera, match_target
from kisscal.target.params import TargetParams
from kisscal.target.resect import CameraFit, choose_camera, resect

__all__ = [
    "CameraFit",
    "TargetMatch",
    "TargetParams",
    "choose_camera",
    "find_dots",
    "find_target_dots",
    "fit_camera",
    "match_target",
    "resect",
]
