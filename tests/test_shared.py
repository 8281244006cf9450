"""Worker processes (kisscal._shared.worker_pool): forked, spawned (as on Windows), or none
inside a daemonic process (a Dask worker)."""

from __future__ import annotations

import multiprocessing
import os
import signal

import numpy as np
import pytest

from kisscal import _shared
from kisscal._shared import START_METHOD_ENV, inherited, start_method, worker_pool
from kisscal.errors import KisscalError


@pytest.mark.parametrize("method", ["fork", "spawn"])
def test_workers_hold_the_payload_in_their_own_processes(method, monkeypatch) -> None:
    monkeypatch.setenv(START_METHOD_ENV, method)
    payload = {"frames": np.arange(6).reshape(2, 3), "name": "cam1"}
    pool = worker_pool(2, payload)
    assert pool is not None
    with pool:
        assert pool._mp_context.get_start_method() == method
        pids = {pool.submit(os.getpid).result() for _ in range(4)}
        held = pool.submit(inherited).result()
    assert os.getpid() not in pids
    np.testing.assert_array_equal(held["frames"], payload["frames"])
    assert held["name"] == "cam1"


def test_spawn_falls_back_to_this_process_for_work_that_cannot_be_pickled(monkeypatch) -> None:
    monkeypatch.setenv(START_METHOD_ENV, "spawn")
    assert worker_pool(2, lambda i: i) is None  # a local function cannot reach a spawned child
    monkeypatch.setenv(START_METHOD_ENV, "fork")
    pool = worker_pool(1, lambda i: i)  # a forked child inherits it
    assert pool is not None
    pool.shutdown()


def test_unknown_start_method_is_a_one_line_error(monkeypatch) -> None:
    monkeypatch.setenv(START_METHOD_ENV, "thread")
    with pytest.raises(KisscalError, match=f"{START_METHOD_ENV}=thread: use one of"):
        start_method()


def _report_start_method(queue) -> None:
    queue.put(start_method())


def test_no_children_inside_a_daemonic_process() -> None:
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    child = context.Process(target=_report_start_method, args=(queue,), daemon=True)
    child.start()
    child.join(60)
    assert queue.get(timeout=10) is None
    assert start_method() in ("fork", "spawn")  # this (not daemonic) process may


_AT_INITIALIZER: list[bool] = []


def _sigint_state() -> tuple[bool, bool, bool]:
    """(held back when the initializer began, ignored, held back) of Ctrl-C here."""
    held = signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, set())
    return _AT_INITIALIZER[0], signal.getsignal(signal.SIGINT) == signal.SIG_IGN, held


@pytest.mark.skipif(not hasattr(signal, "pthread_sigmask"), reason="no signal masks")
def test_a_worker_starts_with_ctrl_c_held_back_and_then_ignores_it(monkeypatch) -> None:
    # held back from the fork to the worker's initializer (a Ctrl-C in between killed the
    # worker and broke the pool), ignored after it; the parent's mask is as it was
    adopt = _shared._adopt

    def recording(*args):
        _AT_INITIALIZER.append(signal.SIGINT in signal.pthread_sigmask(signal.SIG_BLOCK, set()))
        adopt(*args)

    monkeypatch.setattr(_shared, "_adopt", recording)
    monkeypatch.setenv(START_METHOD_ENV, "fork")
    before = signal.pthread_sigmask(signal.SIG_BLOCK, set())
    with worker_pool(1) as pool:
        at_start, ignored, held = pool.submit(_sigint_state).result()
    assert at_start and ignored and not held
    assert signal.pthread_sigmask(signal.SIG_BLOCK, set()) == before
