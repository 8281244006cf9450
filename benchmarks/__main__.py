"""Run benchmarks: ``python -m benchmarks`` (all) or ``python -m benchmarks detect grid``.

A benchmark is a module ``benchmarks/bench_<name>.py`` with a ``main() -> list[str]``
function returning its report lines.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys

import benchmarks
from kisscal.cli import blas  # noqa: F401  (the command line's BLAS threads, before NumPy)


def available() -> list[str]:
    return sorted(
        m.name.removeprefix("bench_")
        for m in pkgutil.iter_modules(benchmarks.__path__)
        if m.name.startswith("bench_")
    )


def run(names: list[str]) -> int:
    known = available()
    for name in names or known:
        if name not in known:
            print(f"benchmarks: unknown benchmark {name!r}; available: {', '.join(known)}")
            return 2
        print(f"== {name}")
        module = importlib.import_module(f"benchmarks.bench_{name}")
        for line in module.main():
            print(line)
    return 0


if __name__ == "__main__":
    sys.exit(run(sys.argv[1:]))
