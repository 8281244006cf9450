"""detect_jobs: several cameras' sequences in one pool, a bad frame failing only its own;
detect_ahead: the same, started in the background."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.detect import ImageJob, detect_blobs, detect_jobs
from kisscal.detect.sequence import detect_ahead
from kisscal.errors import KisscalError
from tests.detect.conftest import KISS, render

TRUTH = np.array([[100.2, 50.7], [300.6, 120.1], [500.5, 200.4]])


def _frame(i: int) -> np.ndarray:
    return render(TRUTH + np.array([i * 0.3, 0.1 * i]), 3.5)


def _shifted(i: int) -> np.ndarray:
    return render(TRUTH[:2] + np.array([5.0 - i * 0.2, 20.0]), 3.0)


def _broken(i: int) -> np.ndarray:
    if i == 3:
        raise KisscalError("frame 3: not a readable image")
    return _frame(i)


@pytest.mark.parametrize("workers", [1, 2])
def test_jobs_of_different_cameras_match_their_own_serial_detection(workers: int) -> None:
    threshold = KISS.replace(threshold=KISS.threshold + 20)
    jobs = [
        ImageJob(_frame, 7, KISS, chunksize=3),
        ImageJob(_shifted, 4, threshold, chunksize=3),
        ImageJob(_frame, 0, KISS),
    ]
    results = dict(detect_jobs(jobs, workers=workers))
    assert sorted(results) == [0, 1, 2]
    assert results[2] == []
    for j, job in enumerate(jobs[:2]):
        expected = [detect_blobs(job.load(i), job.params) for i in range(job.count)]
        assert len(results[j]) == job.count
        for got, want in zip(results[j], expected, strict=True):
            assert np.array_equal(got.x_px, want.x_px) and np.array_equal(got.y_px, want.y_px)
    assert all(len(b) >= 3 for b in results[0]) and all(len(b) == 2 for b in results[1])


def test_a_bad_frame_fails_its_own_job_only() -> None:
    jobs = [ImageJob(_broken, 6, KISS, chunksize=2), ImageJob(_frame, 5, KISS, chunksize=2)]
    results = dict(detect_jobs(jobs, workers=2))
    assert isinstance(results[0], KisscalError) and "frame 3" in str(results[0])
    assert len(results[1]) == 5 and all(len(b) >= 3 for b in results[1])


def test_jobs_detected_ahead_are_those_detected_in_turn() -> None:
    """detect_ahead returns at once; each job's blobs taken later (in any order) are
    detect_jobs' blobs, and a bad frame fails its own job only."""
    jobs = [
        ImageJob(_broken, 6, KISS, chunksize=2),
        ImageJob(_frame, 7, KISS, chunksize=3),
        ImageJob(_shifted, 4, KISS, chunksize=3),
    ]
    ahead = detect_ahead(jobs, workers=2)
    assert ahead is not None
    try:
        got = {j: ahead.result(j) for j in (2, 0, 1)}
    finally:
        ahead.close()
    want = dict(detect_jobs(jobs, workers=1))
    assert isinstance(got[0], KisscalError) and str(got[0]) == str(want[0])
    for j in (1, 2):
        assert len(got[j]) == jobs[j].count
        for a, b in zip(got[j], want[j], strict=True):
            assert np.array_equal(a.x_px, b.x_px) and np.array_equal(a.y_px, b.y_px)
            assert np.array_equal(a.flags, b.flags)


def test_nothing_is_detected_ahead_with_one_worker() -> None:
    assert detect_ahead([ImageJob(_frame, 5, KISS)], workers=1) is None
