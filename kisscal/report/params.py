"""Limits and references the report judges a session by (pass / warn / fail).

The calibration limits are defaults a technician can expect a KISS-like lab to meet;
``kisscal check`` limits, when stored in ``out/limits.json``, replace them (see
:func:`kisscal.report.gather.gather`).
"""

from __future__ import annotations

from dataclasses import dataclass

from kisscal.params import Params, param


@dataclass(frozen=True)
class ReportParams(Params):
    """What the status block of the report compares the session's figures with.

    Attributes
    ----------
    max_grid_px : float
        Each camera's grid residual after linearisation (RMS Euclidean, px).
    max_reproj_px : float
        Each camera's DLT reprojection ``rms_px`` on its control points.
    max_3d_mm : float
        Mean leave-one-rod-out (or leave-points-out) 3D error of the calibration; Kolahi et
        al. 2007 report 2.39 mm for a real lab's DLT.
    min_coverage : float
        Least fraction of a trial's fields in which every trajectory has a sample.
    stick_length_mm : float, optional
        True distance between the two markers of a validation stick (Shafiq et al. 2001
        used one of 502.5 mm). Only when it is given is a trial checked as a stick: one
        with ``stick`` in its name, or another whose two longest trajectories (of at most
        four) keep their distance. Not given (the default), no trial is.
    max_stick_error_mm : float
        Largest mean absolute stick-length error, and largest SD (Shafiq et al. 2001
        measured 1.1 mm and 1.5 mm).
    g_m_s2 : float
        Gravitational acceleration the thrown-marker parabola is compared with.
    max_g_error : float
        Largest relative error of the fitted g (Shafiq et al. 2001: under 1 %).
    viewer_samples : int
        Largest number of marker samples per trial in the 3D viewer (fields are thinned
        evenly to stay under it), which bounds the report's size.
    """

    section = "report"
    max_grid_px: float = param(0.2, unit="px", gt=0)
    max_reproj_px: float = param(0.5, unit="px", gt=0)
    max_3d_mm: float = param(2.0, unit="mm", gt=0)
    min_coverage: float = param(0.95, ge=0, le=1)
    stick_length_mm: float | None = param(None, unit="mm", gt=0)
    max_stick_error_mm: float = param(2.0, unit="mm", gt=0)
    g_m_s2: float = param(9.81, unit="m/s^2", gt=0)
    max_g_error: float = param(0.02, gt=0, lt=1)
    viewer_samples: int = param(4000, ge=100)
