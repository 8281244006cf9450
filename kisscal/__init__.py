"""kisscal: calibration and reconstruction for marker-based multi-camera gait capture.

The pipeline follows the KISS gait lab of METU (see DESIGN.md and the seeds):
blob detection -> grid linearisation -> DLT calibration from rods -> epipolar
matching and triangulation -> Kalman tracking.
"""

__version__ = "0.1.0"
