"""Known-target calibration: a calibration object matched automatically from clicked seeds.

Typical use for one camera (arrays only; :mod:`kisscal.session.routes.target` runs it
for a session)::

    dots = find_target_dots(image, seeds_uv, TargetParams())
    match = match_target(target_xyz, seeds_uv, seeds_xyz, dots, size_px, "cam1")
    match.camera, match.dot, match.visible

Modules: :mod:`~kisscal.target.dots` (dots under uneven light) and
:mod:`~kisscal.target.match` (seed model, matching rounds, camera with lens terms).
"""

from kisscal.target.dots import find_dots, find_target_dots
from kisscal.target.match import TargetMatch, fit_camera, match_target
from kisscal.target.params import TargetParams

__all__ = [
    "TargetMatch",
    "TargetParams",
    "find_dots",
    "find_target_dots",
    "fit_camera",
    "match_target",
]
