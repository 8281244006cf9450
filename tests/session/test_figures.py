"""Stage figures drawn beside the stage: all written when the block ends, errors said."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest
from matplotlib.figure import Figure

from kisscal.session.figures import (
    after_figures,
    drawing_beside,
    submit_figure,
    wait_for_figures,
)
from kisscal.session.runner import each_camera


def square(n: int) -> Figure:
    fig = Figure(figsize=(2, 2))
    fig.add_subplot().plot(range(n), [k * k for k in range(n)])
    fig.text(0.1, 0.9, f"drawn by {os.getpid()}")
    return fig


def guarded(n: int, _lock: object) -> Figure:
    return square(n)


def signed(path: Path) -> Figure:
    """A figure that records which process drew it, beside its PNG."""
    path.with_suffix(".pid").write_text(str(os.getpid()))
    return square(3)


def camera_work(path: Path, _say: object) -> int:
    """A camera's work in a worker process: one figure; returns the worker's id."""
    submit_figure(path, signed, (path,))
    return os.getpid()


def listing(folder: Path) -> tuple[list[str], int]:
    """The PNG files in ``folder`` and the process that looked."""
    return sorted(p.name for p in folder.glob("*.png")), os.getpid()


def broken(_n: int) -> Figure:
    raise RuntimeError("a bug in a figure")


def degenerate(_n: int) -> Figure:
    raise ValueError("nothing to draw")


def test_figures_of_a_block_are_all_written_when_it_ends(tmp_path: Path) -> None:
    paths = [tmp_path / f"f{k}.png" for k in range(4)]
    with drawing_beside():
        for k, path in enumerate(paths):
            submit_figure(path, square, (k + 2,))
        with drawing_beside():  # a stage inside ``kisscal run`` shares the process
            submit_figure(tmp_path / "inner.png", square, (3,))
    for path in [*paths, tmp_path / "inner.png"]:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_report_waits_for_the_figures_of_the_stages_before_it(tmp_path: Path) -> None:
    with drawing_beside():
        for k in range(3):
            submit_figure(tmp_path / f"stage{k}.png", square, (40,))
        wait_for_figures()
        assert sorted(p.name for p in tmp_path.glob("*.png")) == [f"stage{k}.png" for k in range(3)]


def test_a_figure_that_cannot_be_pickled_is_drawn_at_once(tmp_path: Path) -> None:
    with drawing_beside():
        submit_figure(tmp_path / "now.png", guarded, (3, threading.Lock()))
        assert (tmp_path / "now.png").is_file()  # drawn before the block ends


def test_a_broken_figure_fails_the_block_and_a_degenerate_one_is_skipped(tmp_path: Path) -> None:
    with pytest.raises(RuntimeError, match="a bug in a figure"), drawing_beside():
        submit_figure(tmp_path / "skip.png", degenerate, (1,))
        submit_figure(tmp_path / "bug.png", broken, (1,))
    assert not (tmp_path / "skip.png").exists()
    submit_figure(tmp_path / "plain.png", square, (2,))  # no block: drawn now
    assert (tmp_path / "plain.png").is_file()


def test_the_block_own_error_wins(tmp_path: Path) -> None:
    with pytest.raises(KeyError), drawing_beside():
        submit_figure(tmp_path / "bug.png", broken, (1,))
        raise KeyError("the stage failed")


def test_figures_of_worker_processes_are_drawn_by_the_one_figure_process(tmp_path: Path) -> None:
    paths = [tmp_path / f"cam{k}.png" for k in range(4)]
    with drawing_beside():
        workers = set(each_camera(camera_work, paths, "figures", lambda _line: None, 2))
    drawers = {int(p.with_suffix(".pid").read_text()) for p in paths}
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in paths)
    assert os.getpid() not in workers  # the work ran in worker processes
    assert len(drawers) == 1 and not drawers & (workers | {os.getpid()})


def test_work_after_the_figures_runs_in_the_figure_process_once_they_are_drawn(
    tmp_path: Path,
) -> None:
    with drawing_beside():
        for k in range(3):
            submit_figure(tmp_path / f"stage{k}.png", square, (40,))
        names, pid = after_figures(listing, tmp_path)
    assert names == [f"stage{k}.png" for k in range(3)]
    assert pid != os.getpid()
    assert after_figures(listing, tmp_path)[1] == os.getpid()  # no block: here


def logged(log: Path, n: int) -> Figure:
    """:func:`square`, noting each drawing in ``log``."""
    with log.open("a") as f:
        f.write(f"{n}\n")
    return square(n)


def test_a_figure_is_drawn_again_only_when_its_data_changed_or_its_file_is_gone(
    tmp_path: Path,
) -> None:
    log, png = tmp_path / "log.txt", tmp_path / "fig.png"
    with drawing_beside():
        submit_figure(png, logged, (log, 3))
    first = png.read_bytes()
    with drawing_beside():
        submit_figure(png, logged, (log, 3))  # the same figure: kept
    assert log.read_text().split() == ["3"] and png.read_bytes() == first
    submit_figure(png, logged, (log, 4))  # other data: drawn again
    assert log.read_text().split() == ["3", "4"] and png.read_bytes() != first
    png.unlink()
    submit_figure(png, logged, (log, 4))  # its file gone: drawn again
    assert log.read_text().split() == ["3", "4", "4"] and png.is_file()
    submit_figure(png, degenerate, (4,))  # nothing to draw: the old file stays, unkept
    submit_figure(png, logged, (log, 4))
    assert log.read_text().split() == ["3", "4", "4", "4"]
