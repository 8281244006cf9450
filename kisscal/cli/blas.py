"""One thread for the linear-algebra libraries, set before anything imports NumPy.

NumPy, SciPy and OpenCV each load their own OpenBLAS, each sized to a thread per core.
``kisscal run`` already keeps every core busy with its own processes (detection, the
figures, the exports' fits); a BLAS pool in every one of them asks for more threads than
there are cores, for products and decompositions too small to gain from them. On two
cores shared with other work (load about 9), a 1000 x 12 SVD took 0.13 ms on one thread
and a median of 0.26 to 68 ms on two, whose waiting threads spin: 900 small calls (SVDs,
200 x 200 products and solves) cost 0.6 s of processor time on one thread, 8.6 to 18 s
on two. A ``kisscal run`` of the small synthetic session makes too few such calls for
its whole time to show it (0.95x and 1.03x processor time in two rounds of three runs in
turns, within the noise); its outputs are the same to the byte.

The libraries read their variables once, when they are loaded, so this module is
imported first by the command line (:mod:`kisscal.cli`), before NumPy; the worker
processes inherit the environment. A user who sets any of the variables keeps it:
OpenBLAS and MKL fall back to ``OMP_NUM_THREADS`` where their own variable is unset, so
setting theirs beside it would override that choice.
"""

from __future__ import annotations

import os
from collections.abc import MutableMapping

#: The variables that size the BLAS and OpenMP thread pools of NumPy, SciPy and OpenCV.
THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS")


def one_thread(environ: MutableMapping[str, str]) -> None:
    """Set every :data:`THREAD_VARIABLES` to 1 in ``environ`` unless the user set one.

    Parameters
    ----------
    environ
        The environment to change (``os.environ`` for the running process).
    """
    if any(name in environ for name in THREAD_VARIABLES):
        return  # the user's choice, read by the libraries as they read it
    for name in THREAD_VARIABLES:
        environ[name] = "1"


one_thread(os.environ)
