"""``kisscal batch``: many sessions in parallel on Dask (the only module that imports Dask).

Dask is the optional ``batch`` extra (``pip install "kisscal[batch]"``). One session is one
Dask task, run in a worker with one process (``workers=1``): the sessions are the
parallelism. A worker of a cluster started by ``dask worker`` is a daemonic process, which
may not start processes of its own; kisscal's stages then work in the worker's process
(:func:`kisscal._shared.start_method`), figures included.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from kisscal.errors import InputError, KisscalError
from kisscal.session.progress import Echo, quiet
from kisscal.session.run import run

#: What to install when Dask is missing.
INSTALL_BATCH = 'kisscal batch needs Dask: pip install "kisscal[batch]"'


def _dask() -> Any:
    """``dask`` and ``dask.distributed``, or one line saying how to install them."""
    try:
        import dask
        import dask.distributed
    except ImportError:  # the base class: none of the three kinds, an optional install
        raise KisscalError(INSTALL_BATCH) from None
    return dask


def _run_quietly(root: str) -> dict[str, Any]:
    """One session of a batch, run in a Dask worker (single process: the batch is the
    parallelism); returns its summary, or ``{"error": message}`` for a user error."""
    try:
        return run(Path(root), workers=1)
    except KisscalError as exc:
        return {"error": str(exc)}


def batch(sessions: Sequence[Path], scheduler: str | None = None, echo: Echo = quiet) -> list[Path]:
    """``kisscal batch``: run many sessions in parallel on Dask; return the ones that failed.

    Without ``scheduler`` a local cluster (one single-threaded worker process per core)
    is started; with it, the sessions go to that Dask scheduler (a lab cluster), which
    must see the same paths. A session that fails is reported and does not stop the others.
    """
    dask = _dask()
    paths = [Path(s).resolve() for s in sessions]
    if not paths:
        raise InputError("give at least one session folder")
    with dask.config.set({"logging.distributed": "error"}):
        client, cluster = _connect(scheduler, len(paths))
        try:
            futures = client.map(_run_quietly, [str(p) for p in paths], pure=False)
            failed = [p for p, f in zip(paths, futures, strict=True) if not _report(p, f, echo)]
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    echo(f"{len(paths) - len(failed)} of {len(paths)} sessions processed")
    return failed


def _connect(scheduler: str | None, n_sessions: int) -> tuple[Any, Any]:
    """A client of ``scheduler``, or of a local cluster of one single-threaded worker
    process per core (at most one per session), with that cluster."""
    from dask.distributed import Client, LocalCluster

    if scheduler:
        try:
            return Client(scheduler, timeout="10s"), None
        except OSError as exc:
            raise InputError(f"cannot reach the Dask scheduler {scheduler}: {exc}") from None
    n = max(1, min(n_sessions, os.cpu_count() or 1))
    cluster = LocalCluster(
        n_workers=n, threads_per_worker=1, dashboard_address=None, silence_logs=40
    )
    return Client(cluster), cluster


def _report(path: Path, future: Any, echo: Echo) -> bool:
    """Print one session's outcome; True when it succeeded."""
    try:
        summary = future.result()
    except Exception as exc:  # one failed session must not stop the others
        summary = {"error": str(exc)}
    if "error" in summary:
        echo(f"FAILED  {path}: {summary['error']}")
        return False
    n_traj = sum(t.get("trajectories", 0) for t in summary["trials"].values())
    echo(f"ok      {path}: {len(summary['trials'])} trials, {n_traj} trajectories")
    return True
