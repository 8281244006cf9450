"""Triangulation, as the reconstruction stage uses it.

The solver lives beside the DLT projection it inverts (:mod:`kisscal.dlt.triangulate`), so
that calibration checks and reconstruction share it without an import cycle between the
``dlt`` and ``recon`` packages; this module keeps the reconstruction stage's import path.
"""

from kisscal.dlt.triangulate import Triangulation, triangulate, triangulate_observations

__all__ = ["Triangulation", "triangulate", "triangulate_observations"]
