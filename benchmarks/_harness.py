"""Tiny harness shared by the benchmarks: best-of-N timing and a uniform report line."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Timing:
    """Best wall time of ``repeat`` runs of one callable, in seconds."""

    name: str
    seconds: float
    items: int
    unit: str

    @property
    def per_second(self) -> float:
        return self.items / self.seconds if self.seconds > 0 else float("inf")


def best_of(name: str, fn: Callable[[], object], items: int, unit: str, repeat: int = 3) -> Timing:
    """Time ``fn`` ``repeat`` times and keep the fastest run (least disturbed by load)."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return Timing(name, best, items, unit)


def best_of_pair(
    first: tuple[str, Callable[[], object]],
    second: tuple[str, Callable[[], object]],
    items: int,
    unit: str,
    repeat: int = 5,
    clock: Callable[[], float] = time.perf_counter,
) -> tuple[Timing, Timing]:
    """Best of ``repeat`` runs of two callables, taken in turns: a change of load on a
    shared machine then falls on both, not on whichever ran during it. ``clock``:
    ``time.process_time`` counts this process's CPU time only (less noisy on a machine
    shared with other jobs, for single-threaded code)."""
    best = [float("inf"), float("inf")]
    for _ in range(repeat):
        for k, (_name, fn) in enumerate((first, second)):
            t0 = clock()
            fn()
            best[k] = min(best[k], clock() - t0)
    return Timing(first[0], best[0], items, unit), Timing(second[0], best[1], items, unit)


def report(subject: Timing, reference: Timing | None = None) -> str:
    """One line: throughput of ``subject`` and, if given, its time ratio to ``reference``."""
    line = (
        f"{subject.name:<40s} {subject.per_second:12.1f} {subject.unit}/s"
        f"  ({subject.seconds:.4f} s)"
    )
    if reference is not None:
        ratio = subject.seconds / reference.seconds
        line += f"  ratio to {reference.name}: {ratio:.2f}x"
    return line
