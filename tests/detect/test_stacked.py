"""detect_frames (frames stacked, every step run once per stack) gives what detect_blobs
gives frame by frame: same blobs, same order, same flags, the same centroids to the bit,
each frame reading its own background, growth, typical marker and border."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import kisscal.detect.blobs as fl
from kisscal.detect import Blobs, DetectionParams, detect_blobs
from kisscal.detect.advanced import Grouping
from kisscal.detect.configure import configure_detection
from kisscal.detect.detach import detach_from_large
from kisscal.detect.groups import measure_groups
from kisscal.detect.pipeline import detect_frames
from kisscal.detect.scan import group_runs
from kisscal.io.frames import read_image
from tests.detect.conftest import KISS, render

REAL = Path(__file__).resolve().parents[2] / "fixtures" / "real" / "openptv-cavity"
COLUMNS = ("x_px", "y_px", "x_binary_px", "y_binary_px", "pixels", "w_px", "h_px", "valid")


def _same(got: list[Blobs], want: list[Blobs]) -> None:
    assert len(got) == len(want)
    for k, (g, w) in enumerate(zip(got, want, strict=True)):
        assert len(g) == len(w), f"frame {k}: {len(g)} blobs, {len(w)} alone"
        assert np.array_equal(g.flags, w.flags), f"frame {k}"
        for name in COLUMNS:
            a, b = getattr(g, name), getattr(w, name)
            assert np.array_equal(a, b), f"frame {k} {name}: {a} vs {b}"


def _ring_at_bottom() -> np.ndarray:
    """An LED ring cut by the frame's bottom border: the opening leaves slivers at the
    border that only the frame's own border tells apart from markers."""
    return render(np.array([[300.0, 291.0]]), 14.0, peak=255.0)


def _scenes() -> list[np.ndarray]:
    """Frames that take every grouping step: rings with a marker attached (also cut by
    the top and bottom borders), a dot with a streak, touching and lone markers near the
    borders, an empty frame and an all-white one among them."""
    rng = np.random.default_rng(3)
    frames = []
    for i in range(7):
        spots = np.column_stack([rng.uniform(20, 730, 12), rng.uniform(3, 288, 12)])
        spots[0] = [100 + 10 * i, 1.5]  # on the top border
        spots[1] = [400 + 5 * i, 289.0]  # on the bottom border
        spots[2:4] = [[600.0, 150.0], [607.5 + 0.3 * i, 151.0]]  # a touching pair
        frames.append(render(spots, rng.uniform(2.5, 4.0, 12), noise_sigma=1.5, rng=rng))
    led = np.maximum(render(np.array([[200.0, 100.0]]), 9.0, peak=255.0), frames[1])
    frames[1] = np.maximum(led, render(np.array([[200.0 + 11.0, 102.0]]), 3.0))
    frames[2] = np.maximum(frames[2], _ring_at_bottom())
    frames[3] = np.maximum(frames[3], _ring_at_bottom()[::-1])  # cut by the top border
    streak = render(np.array([[300.0, 120.0]]), 4.0)
    streak[119:122, 305:330] = 200  # a thin streak off a dot
    frames[4] = np.maximum(frames[4], streak)
    frames.insert(5, np.full((291, 752), 6, np.uint8))  # nothing to find
    frames.insert(6, np.full((291, 752), 240, np.uint8))  # all white: hopeless
    return frames


def test_the_bottom_ring_tests_the_frame_border() -> None:
    # without the border rule the ring's slivers become markers: a stack that lost each
    # frame's border would not give the frame's own blobs
    white = _ring_at_bottom() >= KISS.threshold
    grouping = Grouping.start(group_runs(white))
    table = measure_groups(grouping.runs)
    framed = detach_from_large(grouping, table, KISS, shape=white.shape)
    loose = detach_from_large(grouping, table, KISS)
    assert len(measure_groups(framed.runs)) != len(measure_groups(loose.runs))


@pytest.mark.parametrize("params", [KISS, KISS.replace(closeness_rows=3, closeness_x_px=2.0)])
def test_stacked_frames_give_each_frame_its_own_blobs(params: DetectionParams) -> None:
    frames = _scenes()
    want = [detect_blobs(f, params) for f in frames]
    assert sum(len(b) for b in want) > 60
    _same(detect_frames(frames, params), want)


def test_frames_of_other_sizes_and_types_among_them() -> None:
    frames = _scenes()[:4]
    frames.insert(2, frames[2][:200, :500].copy())  # another size: a stack of its own
    frames.append(frames[0] >= KISS.threshold)  # a thresholded frame
    frames.append(frames[1].astype(np.uint16) * 257)  # a 16-bit frame
    _same(detect_frames(frames, KISS), [detect_blobs(f, KISS) for f in frames])


def test_stacks_are_cut_at_the_pixel_bound(monkeypatch: pytest.MonkeyPatch) -> None:
    import kisscal.detect.pipeline as pipeline

    frames = _scenes()
    monkeypatch.setattr(pipeline, "STACK_PX", 3 * frames[0].size)  # stacks of three
    _same(detect_frames(frames, KISS), [detect_blobs(f, KISS) for f in frames])


@pytest.mark.parametrize("name", ["cal1", "cal4", "particles1"])
def test_real_frames_stacked_give_their_own_blobs(name: str) -> None:
    image = read_image(REAL / f"{name}.png")
    params = configure_detection([image]).params
    frames = [image, image[::-1].copy(), image[:, ::-1].copy(), np.roll(image, 17, axis=0)]
    want = [detect_blobs(f, params) for f in frames]
    assert all(len(b) > 10 for b in want)
    _same(detect_frames(frames, params), want)


def _unlike_frames() -> list[np.ndarray]:
    """Frames of one size unlike in all that a frame gives as a whole: background level
    (weighted centroids, the cores' contrast), blur (the spots' growth), marker size (the
    split tests' typical marker); each with spots on its top and bottom borders, three
    touching markers and a dim lit patch with a dot on it (cores)."""
    rng = np.random.default_rng(11)
    frames = []
    # background, blur, marker radius, the dot's height over its patch: the cut of the
    # cores (half maximum, at least the frame's contrast) changes with the background
    looks = [(6, 0.6, 3.0, 60), (30, 1.3, 4.5, 30), (14, 0.9, 2.4, 70), (3, 0.4, 5.5, 80)]
    looks.append((22, 1.0, 3.5, 30))
    for k, (level, blur, radius, height) in enumerate(looks):
        spots = np.column_stack([rng.uniform(30, 560, 14), rng.uniform(10, 280, 14)])
        spots[0] = [100 + 7 * k, 1.5]
        spots[1] = [400 + 3 * k, 289.5]
        spots[2:5] = [[600.0, 150.0], [600 + 1.7 * radius, 150.5], [600 + 3.4 * radius, 151]]
        image = render(spots, radius, blur_px=blur, background=level, noise_sigma=1.0, rng=rng)
        patch = image[60:78, 200:250]
        np.maximum(patch, 42 + 6 * k, out=patch)
        dot = render(np.array([[225.0 + k, 69.0]]), 3.0, peak=height, background=0)
        frames.append(np.maximum(image, dot + patch.min() * (dot > 0)).astype(np.uint8))
    return frames


@pytest.mark.parametrize(
    "params",
    [KISS, KISS.replace(centroid_highpass_px=11), KISS.replace(background_tile_px=32)],
    ids=["global", "highpass", "local"],
)
def test_each_frame_reads_its_own_frame(params: DetectionParams) -> None:
    frames = _unlike_frames()
    want = [detect_blobs(f, params) for f in frames]
    flags = np.bitwise_or.reduce(np.concatenate([b.flags for b in want]))
    assert flags & fl.SPLIT_TOUCHING and flags & fl.DETACHED
    _same(detect_frames(frames, params), want)
