"""Rod recognition on busy images: time and peak memory against the number of clutter blobs.

A rod image of the tests' KISS-like rig (24 markers, 752 x 291) plus ``n`` clutter blobs
spread over the image; each case runs in a fresh process so that its peak resident memory
(``ru_maxrss``) is its own. Run ``python -m tests.dlt.busy_rods [n ...]`` from the
repository root.
"""

from __future__ import annotations

import resource
import subprocess
import sys
import time

import numpy as np


def one(n_extra: int) -> str:
    """Recognise the rods of one image with ``n_extra`` clutter blobs; one report line."""
    from kisscal.dlt import recognise_rods
    from kisscal.errors import KisscalError
    from tests.dlt.conftest import kiss_rig, rod_image

    rig = kiss_rig(0)
    blobs, truth = rod_image(rig, 0, np.random.default_rng(5), n_extra=n_extra)
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    try:
        match = recognise_rods(blobs, rig.rods, camera="cam1")
        right = np.array_equal(match.blob_index.ravel(), truth)
        result = "all 24 markers right" if right else "WRONG"
    except KisscalError as exc:
        result = f"refused: {str(exc)[:70]}..."
    seconds = time.perf_counter() - t0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return (
        f"{len(blobs):6d} {seconds:8.2f} {peak / 1024:9.0f} {(peak - before) / 1024:9.0f}  {result}"
    )


def main(counts: tuple[int, ...]) -> list[str]:
    lines = [" blobs  time_s  peak_MB  added_MB  result"]
    for n in counts:
        out = subprocess.run(
            [sys.executable, "-m", "tests.dlt.busy_rods", "--one", str(n)],
            capture_output=True,
            text=True,
            check=True,
        )
        lines.append(out.stdout.rstrip())
    return lines


if __name__ == "__main__":
    if sys.argv[1:2] == ["--one"]:
        print(one(int(sys.argv[2])))
    else:
        counts = tuple(int(a) for a in sys.argv[1:]) or (8, 30, 60, 100, 115, 300, 1300, 5000)
        print("\n".join(main(counts)))
