"""The wall time a command would take on free cores, read from its parallelism profile.

On a machine shared with other work, a command's wall time says how busy the machine
was as much as how long the command takes: two cores shared by twenty runnable processes
give it a tenth of each. What does not move with the load is its profile: at every moment,
how many of its processes are runnable and how much processor time they spend. A
:class:`TreeSampler` reads both from ``/proc`` (Linux) every few milliseconds for the
command's process and all its descendants; :meth:`TreeSampler.free_wall` then adds up,
moment by moment, the work done over the number of cores it could have used (its
runnable processes, at most the cores): the wall time on that many free cores, the
processes' start-up and their waits included, the other users' load left out.
"""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

#: Processor-time ticks a second (``/proc``'s unit).
_TICKS = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100


def _tree(pid: int) -> list[int]:
    """``pid`` and its descendants (``/proc/<pid>/task/<tid>/children``)."""
    found, todo = [], [pid]
    while todo:
        p = todo.pop()
        found.append(p)
        try:
            for task in os.listdir(f"/proc/{p}/task"):
                todo += [
                    int(c) for c in Path(f"/proc/{p}/task/{task}/children").read_text().split()
                ]
        except OSError:  # ended meanwhile
            continue
    return found


def _state(pid: int) -> tuple[bool, float] | None:
    """Whether ``pid`` is runnable, and its processor time so far (s); None once ended."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = stat[stat.rindex(")") + 2 :].split()  # after the command's name
    return fields[0] == "R", (int(fields[11]) + int(fields[12])) / _TICKS


class TreeSampler(threading.Thread):
    """Samples a process tree every ``period`` s until :meth:`stop`."""

    def __init__(self, pid: int, period: float = 0.02) -> None:
        super().__init__(daemon=True)
        self.pid, self.period = pid, period
        self.samples: list[tuple[float, int]] = []  # (work since the last sample, runnable)
        self._done = threading.Event()

    def run(self) -> None:
        spent: dict[int, float] = {}
        while not self._done.is_set():
            work, runnable = 0.0, 0
            for p in _tree(self.pid):
                state = _state(p)
                if state is None:
                    continue
                running, cpu = state
                work += cpu - spent.get(p, 0.0)
                spent[p] = cpu
                runnable += running
            self.samples.append((work, runnable))
            time.sleep(self.period)

    def stop(self) -> None:
        self._done.set()
        self.join()

    def free_wall(self, cores: int) -> float:
        """The tree's wall time on ``cores`` free cores: each interval's work over the
        cores its runnable processes could use (the mean of its two ends, at least one)."""
        total = 0.0
        for (work, r1), (_w, r0) in zip(self.samples[1:], self.samples, strict=False):
            total += work / min(max((r0 + r1) / 2, 1.0), cores)
        return total + (self.samples[0][0] if self.samples else 0.0)
