"""Small helpers several stages share, with one definition each.

- :func:`rms_px`: the residual figure of DESIGN.md, ``sqrt(mean(du^2 + dv^2))``;
- :func:`similarity_normaliser` and :func:`apply_transform`: the conditioning of
  coordinates before a linear solve (Hartley 1997);
- :func:`lexsort_ints`: :func:`numpy.lexsort` of integer keys, by radix passes;
- :func:`n_distinct`: the number of distinct integers, without sorting them;
- :func:`worker_pool` and :func:`inherited`: worker processes that inherit their work
  (forked where the system can fork, spawned elsewhere, none inside a daemonic process);
- :func:`as_points`: the one check of a caller's point array (``(n, 2)`` or ``(n, 3)``);
- :func:`new_figure`: a matplotlib figure on an Agg canvas, matplotlib imported only then.

References
----------
Hartley, R. I. (1997). In defense of the eight-point algorithm. IEEE Transactions on
Pattern Analysis and Machine Intelligence, 19(6), 580-593.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import signal
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from kisscal.errors import InputError

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def rms_px(residuals_px: ArrayLike) -> float:
    """``sqrt(mean(du^2 + dv^2))`` of 2D residual vectors (px); NaN when there are none.

    Examples
    --------
    >>> rms_px([[3.0, 4.0], [0.0, 0.0]])
    3.5355339059327378
    >>> rms_px(np.zeros((0, 2)))
    nan
    """
    d = np.asarray(residuals_px, dtype=float).reshape(-1, 2)
    return float(np.sqrt(np.mean(np.sum(d * d, axis=1)))) if len(d) else float("nan")


def similarity_normaliser(points: ArrayLike) -> NDArray[np.float64]:
    """Homogeneous transform that centres ``points`` (N, d) and scales their mean distance
    from the centre to ``sqrt(d)`` (Hartley 1997).

    Examples
    --------
    >>> T = similarity_normaliser([[0.0, 0.0], [2.0, 0.0]])
    >>> apply_transform(T, [[0.0, 0.0], [2.0, 0.0]]).round(4)
    array([[-1.4142,  0.    ],
           [ 1.4142,  0.    ]])
    """
    points = np.asarray(points, dtype=float)
    d = points.shape[1]
    centre = points.mean(axis=0)
    s = np.sqrt(d) / np.linalg.norm(points - centre, axis=1).mean()
    T = np.eye(d + 1)
    T[:d, :d] *= s
    T[:d, d] = -s * centre
    return T


def apply_transform(T: ArrayLike, points: ArrayLike) -> NDArray[np.float64]:
    """Points (N, d) through an affine homogeneous transform (d + 1, d + 1)."""
    T = np.asarray(T, dtype=float)
    return np.asarray(points, dtype=float) @ T[:-1, :-1].T + T[:-1, -1]


def lexsort_ints(keys: Sequence[ArrayLike]) -> NDArray[np.intp]:
    """:func:`numpy.lexsort` of integer keys (the last key primary), by 16-bit radix passes.

    numpy sorts integers of 16 bits or less by a stable radix sort, linear in the rows and
    ~20x faster than the merge sorts of ``lexsort`` on 10^4-10^5 rows; sorting every key
    16 bits at a time, least significant first, gives the same (unique, stable) order.

    Examples
    --------
    >>> lexsort_ints([[1, 0, 1, 0], [5, 5, 2, 70000]])
    array([2, 1, 0, 3])
    """
    keys = [np.asarray(k, dtype=np.int64).ravel() for k in keys]
    n = len(keys[0]) if keys else 0
    order = np.arange(n)
    if n == 0:
        return order
    for key in keys:
        key = key - key.min()
        top, shift = int(key.max()), 0
        while True:
            digit = ((key[order] >> shift) & 0xFFFF).astype(np.uint16)
            order = order[np.argsort(digit, kind="stable")]
            shift += 16
            if top >> shift == 0:
                break
    return order


def true_runs(mask: ArrayLike) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Start and stop (exclusive) of each run of True in a 1-D mask.

    Examples
    --------
    >>> starts, stops = true_runs([False, True, True, False, True])
    >>> starts.tolist(), stops.tolist()
    ([1, 4], [3, 5])
    """
    padded = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]]).astype(np.int8)
    d = np.diff(padded)
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def n_distinct(values: ArrayLike) -> int:
    """Number of distinct integers in ``values`` (``len(np.unique(values))``).

    Counts them in a table over their range when it is not much larger than their
    number (field numbers of a trial): no sort.

    Examples
    --------
    >>> n_distinct([3, 1, 3, 7])
    3
    """
    values = np.asarray(values, dtype=np.int64).ravel()
    if len(values) == 0:
        return 0
    lo, hi = int(values.min()), int(values.max())
    if hi - lo > 4 * len(values) + 64:
        return len(np.unique(values))
    seen = np.zeros(hi - lo + 1, dtype=bool)
    seen[values - lo] = True
    return int(np.count_nonzero(seen))


def as_points(points: ArrayLike, dim: int, name: str = "points") -> NDArray[np.float64]:
    """A caller's points as a float ``(n, dim)`` array, or an :class:`InputError`.

    One point of ``dim`` coordinates may be given as a flat ``(dim,)`` array. Anything
    else (a ``(2, 6)`` array for ``dim`` 3, a transposed table) is refused with its shape
    in the message rather than reshaped into points it never held.

    Examples
    --------
    >>> as_points([1.0, 2.0, 3.0], 3).shape
    (1, 3)
    >>> as_points(np.zeros((2, 6)), 3)
    Traceback (most recent call last):
    ...
    kisscal.errors.InputError: points must have shape (n, 3), got (2, 6)
    """
    try:
        array = np.asarray(points, dtype=float)
    except (TypeError, ValueError) as error:
        raise InputError(f"{name} must be an array of numbers, shape (n, {dim}): {error}") from None
    if array.ndim == 1 and array.shape[0] == dim:
        array = array[None, :]
    elif array.ndim == 1 and array.size == 0:
        array = array.reshape(0, dim)
    if array.ndim != 2 or array.shape[1] != dim:
        raise InputError(f"{name} must have shape (n, {dim}), got {array.shape}")
    return array


def in_image(
    uv_px: ArrayLike, size_px: tuple[int, int], margin_px: float = 0.0
) -> NDArray[np.bool_]:
    """Whether pixels (..., 2) lie on an image of ``size_px`` (width, height), ``margin_px``
    inside its border: pixel centres are whole numbers, so the image spans -0.5 to
    ``width - 0.5`` (NaN is on no image)."""
    uv = np.asarray(uv_px, dtype=float)
    w, h = size_px
    lo = margin_px - 0.5
    return (
        (uv[..., 0] >= lo)
        & (uv[..., 0] <= w - 0.5 - margin_px)
        & (uv[..., 1] >= lo)
        & (uv[..., 1] <= h - 0.5 - margin_px)
    )


def new_figure(width_in: float, height_in: float, constrained: bool = True) -> Figure:
    """A matplotlib figure on an Agg canvas: no pyplot state.

    With ``constrained`` (constrained layout) matplotlib places the panels around their
    labels, which costs it a second drawing pass on saving; a figure of many alike panels
    places them itself (``constrained=False``, :func:`kisscal.report.figures.panel_grid`).
    matplotlib is imported here, when a figure is drawn, so that the modules drawing
    figures import without it.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), layout="constrained" if constrained else None)
    FigureCanvasAgg(fig)
    return fig


def fixed_margins(
    size_in: tuple[float, float],
    shape: tuple[int, int],
    margins_in: tuple[float, float, float, float],
    gaps_in: tuple[float, float],
) -> dict[str, float]:
    """Subplot parameters (``left``, ``right``, ``bottom``, ``top``, ``wspace``,
    ``hspace``) that place a ``shape`` (rows, columns) grid of panels in a figure of
    ``size_in`` (width, height) inches with ``margins_in`` (left, right, bottom, top) and
    ``gaps_in`` (between columns, between rows) in inches.

    For ``fig.subplots_adjust`` or a grid spec: a layout fixed once instead of
    matplotlib's constrained layout, whose placement draws every panel a second time on
    saving (a third of a stage figure's time).
    """
    (width, height), (rows, cols) = size_in, shape
    left, right, bottom, top = margins_in
    gap_x, gap_y = gaps_in
    panel_w = (width - left - right - (cols - 1) * gap_x) / cols
    panel_h = (height - bottom - top - (rows - 1) * gap_y) / rows
    return {
        "left": left / width,
        "right": 1 - right / width,
        "bottom": bottom / height,
        "top": 1 - top / height,
        "wspace": gap_x / panel_w,
        "hspace": gap_y / panel_h,
    }


_INHERITED: dict[str, Any] = {}

#: Environment variable naming the start method of worker processes, ``fork`` or
#: ``spawn``: ``spawn`` on Linux runs kisscal as it runs on Windows (and in tests does).
START_METHOD_ENV = "KISSCAL_START_METHOD"


def _adopt(payload: Any, packed: bool) -> None:
    # A forked child inherits OpenCV's thread pool without its threads: once the parent has
    # run a parallel OpenCV call (a detection survey does), the child's first parallel call
    # can wait forever. A worker process needs no threads of its own.
    cv2.setNumThreads(0)
    # Ctrl-C at a terminal reaches every process of the group: the parent alone reports
    # it (one line), and ends the workers; a worker's own KeyboardInterrupt would print
    # a traceback per process.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "pthread_sigmask"):  # held back since the fork: now ignored
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    _INHERITED["payload"] = pickle.loads(payload) if packed else payload


class _Pool(ProcessPoolExecutor):
    """A process pool that, left by an exception (Ctrl-C above all), ends its workers at
    once: the standard pool would first finish every task already queued."""

    def _spawn_process(self) -> None:
        # A Ctrl-C between the fork and the worker's initializer (which ignores it) killed
        # the worker with a traceback and broke the pool, and the run ended on
        # BrokenProcessPool, not "interrupted" (whole-suite run, Ctrl-C 0.5 s in): the
        # child starts with it held back, the parent receives its own once forked.
        if not hasattr(signal, "pthread_sigmask"):  # Windows: no signal masks
            super()._spawn_process()  # type: ignore[misc]
            return
        held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
        try:
            super()._spawn_process()  # type: ignore[misc]
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> bool:
        if exc_type is None:
            return bool(super().__exit__(exc_type, exc, tb))
        for process in list((self._processes or {}).values()):
            process.terminate()
        self.shutdown(wait=True, cancel_futures=True)
        return False


def start_method() -> str | None:
    """How :func:`worker_pool` starts processes here: ``fork`` where the system has it
    (the children inherit the parent's memory), else ``spawn`` (Windows: the children
    import kisscal afresh and receive their work pickled); :data:`START_METHOD_ENV`
    chooses one. ``None`` inside a daemonic process, which may not start children: a
    worker of a Dask cluster (``dask worker``), or of another process pool.
    """
    if multiprocessing.current_process().daemon:
        return None
    methods = multiprocessing.get_all_start_methods()
    forced = os.environ.get(START_METHOD_ENV, "").strip()
    if forced:
        if forced not in methods or forced == "forkserver":
            raise InputError(
                f"{START_METHOD_ENV}={forced}: use one of "
                f"{', '.join(m for m in methods if m != 'forkserver')}"
            )
        return forced
    return "fork" if "fork" in methods else "spawn"


def worker_pool(workers: int, payload: Any = None) -> ProcessPoolExecutor | None:
    """A pool of ``workers`` processes that hold ``payload`` (:func:`inherited`).

    Forked children share the parent's memory, so the payload (image loaders, the work
    function and its inputs) is never pickled; spawned ones get it pickled once each.
    Only the tasks' arguments and results travel per task. ``None`` where no process
    can be started (:func:`start_method`) or the payload cannot be pickled for a spawned
    child (a local function): the caller then works in its own process.
    """
    method = start_method()
    if method is None:
        return None
    packed = method != "fork"
    if packed:
        try:
            payload = pickle.dumps(payload, protocol=pickle.HIGHEST_PROTOCOL)
        except (pickle.PicklingError, TypeError, AttributeError):
            return None
    return _Pool(
        max_workers=workers,
        mp_context=multiprocessing.get_context(method),
        initializer=_adopt,
        initargs=(payload, packed),
    )


def inherited() -> Any:
    """The payload this worker process of :func:`worker_pool` holds."""
    return _INHERITED["payload"]
