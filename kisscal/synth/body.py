"""The pelvis both synthetic walkers share: the kinematic one (:mod:`kisscal.synth.motion`)
and the grounded one (:mod:`kisscal.synth.walker`).

Marker positions in the pelvis frame (x forward, y to the left, z up, mm, at the
reference stature) and the capsule that stands for the pelvis in occlusion tests.
"""

from __future__ import annotations

import numpy as np

#: Pelvis markers of the KISS set with the two anterior ones of the 15-marker set.
PELVIS_MARKERS = {
    "SACR": np.array([-110.0, 0.0, 80.0]),
    "RASI": np.array([100.0, -120.0, 60.0]),
    "LASI": np.array([100.0, 120.0, 60.0]),
}
#: Radius of the pelvis capsule and half its length, from hip to hip (mm).
PELVIS_RADIUS_MM = 90.0
PELVIS_HALF_LENGTH_MM = 80.0
