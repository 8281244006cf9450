"""kisscal: calibration and reconstruction for marker-based multi-camera gait capture.

The pipeline follows the KISS gait lab of METU (Shafiq et al. 2001; Küçük 2005):
blob detection -> grid linearisation -> DLT calibration from rods -> epipolar
matching and triangulation -> Kalman tracking.
"""

__version__ = "0.1.0"
