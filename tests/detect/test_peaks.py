"""The peaks route (particle frames, after Maas et al. 1993) and its automatic choice."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kisscal.detect import DetectionParams, detect_blobs
from kisscal.detect.configure import configure_detection
from kisscal.detect.peaks import detect_peaks, grow_regions, highpass, regions
from kisscal.detect.pipeline import detect_frames
from kisscal.errors import InputError
from kisscal.io.frames import read_image
from tests.detect.real_acceptance import score_targets

FIXTURES = Path(__file__).resolve().parents[2] / "fixtures" / "real" / "openptv-cavity"
PEAKS = DetectionParams(route="peaks", threshold=9.0, peak_highpass_px=25)


def _spot(shape: tuple[int, int], x: float, y: float, peak: float, sigma: float) -> np.ndarray:
    yy, xx = np.mgrid[: shape[0], : shape[1]]
    return peak * np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / (2 * sigma**2))


def test_highpass_takes_a_ramp_to_zero_and_keeps_a_spot() -> None:
    ramp = np.tile(np.linspace(10, 200, 120, dtype=np.float32), (100, 1))
    spot = _spot((100, 120), 60.3, 50.0, 100.0, 1.2)
    hp = highpass(ramp + spot, 25)
    assert np.abs(hp[20:80, 20:100][spot[20:80, 20:100] < 1e-3]).max() < 1.0
    assert hp[50, 60] > 90.0


def test_spots_found_at_their_centres() -> None:
    rng = np.random.default_rng(3)
    grid = np.stack(np.meshgrid(np.arange(30, 180, 25), np.arange(30, 180, 25)), -1)
    truth = grid.reshape(-1, 2) + rng.uniform(-3, 3, (36, 2))  # 36 spots 19-31 px apart
    image = rng.normal(20, 1.0, (200, 200))
    for x, y in truth:
        image += _spot(image.shape, x, y, 150.0, 1.1)
    blobs = detect_peaks(image.clip(0, 255).astype(np.uint8), PEAKS).valid_only()
    assert len(blobs) == len(truth)
    d = np.hypot(*(blobs.xy_px[:, None] - truth[None]).T).min(axis=1)
    assert d.max() < 0.2, d.max()


def test_a_particle_on_a_lit_wall_is_cut_out_of_it() -> None:
    # a wall lit 40 levels over 30 x 30 px (larger than any particle) with a particle on it
    hp = np.zeros((80, 80), np.float32)
    hp[20:50, 20:50] = 40.0
    hp += _spot(hp.shape, 35.0, 33.0, 150.0, 1.0).astype(np.float32)
    labels, count = regions(hp, 9.0, (200, None, None))
    assert count == 1
    ys, xs = np.nonzero(labels == 1)
    assert len(xs) < 30 and abs(xs.mean() - 35.0) < 0.5 and abs(ys.mean() - 33.0) < 0.5
    assert regions(hp, 9.0)[1] == 1  # no limit: the wall is one region
    assert (regions(hp, 9.0)[0] > 0).sum() == 900


def test_a_faint_particle_on_a_lit_wall_is_cut_out_below_twice_the_threshold() -> None:
    # a wall 3 levels over the threshold, larger than a particle, under a particle whose
    # peak (17) is below twice the threshold: cut at the first level the wall falls below
    hp = np.zeros((80, 80), np.float32)
    hp[20:50, 20:50] = 12.0
    spot = _spot(hp.shape, 34.6, 36.3, 5.0, 1.2).astype(np.float32)
    hp += np.where(spot > 0.5, spot, 0)
    labels, count = regions(hp, 9.0, (200, None, None))
    assert count == 1
    ys, xs = np.nonzero(labels == 1)
    w = hp[ys, xs] - 9.0
    assert abs(np.sum(w * xs) / w.sum() - 34.6) < 0.3 and abs(np.sum(w * ys) / w.sum() - 36.3) < 0.3


def test_border_regions_dropped_and_small_ones_invalid() -> None:
    image = np.full((60, 60), 10, np.uint8)
    image[0:3, 20:23] = 200  # touches the border
    image[30, 30] = 200  # one pixel: narrower than two
    image[40:43, 40:43] = 200
    blobs = detect_peaks(image, PEAKS)
    assert len(blobs) == 2
    assert blobs.valid.tolist() == [False, True]
    assert detect_frames([image, image], PEAKS)[1].xy_px.tolist() == blobs.xy_px.tolist()
    with pytest.raises(InputError, match="grey images"):
        detect_blobs(image > 100, PEAKS)


def test_a_bright_particle_beside_a_faint_one_is_grown_apart() -> None:
    # a faint spot (peak 40) and a bright one (peak 220) 6 px apart, joined above 9 by a
    # faint bridge: no step from the faint side climbs into the bright particle's core
    hp = np.zeros((40, 60), np.float32)
    hp += _spot(hp.shape, 22.0, 20.0, 40.0, 2.5).astype(np.float32)
    hp += _spot(hp.shape, 28.0, 20.0, 220.0, 0.9).astype(np.float32)
    hp[18:23, 22:29] = np.maximum(hp[18:23, 22:29], 20.0)
    assert grow_regions(hp, 9.0, np.inf)[1] == 1  # no discontinuity: one region
    labels, count = grow_regions(hp, 9.0, 100.0)
    assert count == 2
    bright = labels == labels[20, 28]
    assert labels[20, 22] != labels[20, 28] and labels[20, 22] > 0
    ys, xs = np.nonzero(bright)
    w = hp[bright] - 9.0
    assert abs(np.sum(w * xs) / w.sum() - 28.0) < 0.1 and abs(np.sum(w * ys) / w.sum() - 20.0) < 0.1
    # the faint spot keeps the bridge it reaches first; the bright one keeps only its core
    assert (labels == labels[20, 22]).sum() > bright.sum()


def test_peaks_that_reach_one_another_are_one_region_whatever_the_scan_order() -> None:
    rng = np.random.default_rng(11)
    hp = np.zeros((80, 80), np.float32)
    for _ in range(25):  # spots of every brightness, some touching
        x, y = rng.uniform(8, 72, 2)
        hp += _spot(hp.shape, x, y, rng.uniform(20, 240), rng.uniform(0.7, 2.0)).astype(np.float32)
    hp += rng.uniform(0, 3, hp.shape).astype(np.float32)
    labels, count = grow_regions(hp, 9.0, 100.0)
    for flip in (np.fliplr, np.flipud, np.transpose):
        other, n = grow_regions(np.ascontiguousarray(flip(hp)), 9.0, 100.0)
        assert n == count
        back = flip(other)
        pairs = np.unique(np.column_stack([labels.ravel(), back.ravel()]), axis=0)
        assert len(pairs) == count + 1  # the same regions, one to one (and the background)
    # two noise maxima on one particle (a dip of 3 levels) stay one region
    twin = _spot((30, 30), 14.0, 15.0, 120.0, 1.5) + _spot((30, 30), 17.0, 15.0, 120.0, 1.5)
    assert grow_regions(twin.astype(np.float32), 9.0, 100.0)[1] == 1


def test_real_particle_crop_chooses_the_peaks_route_and_finds_openptvs_targets() -> None:
    image = read_image(FIXTURES / "particles1.png")
    targets = np.loadtxt(FIXTURES / "particles1_targets.csv", delimiter=",", skiprows=1)
    setup = configure_detection([image])
    assert setup.params.route == "peaks", setup.choices["route"].why
    score = score_targets(detect_blobs(image, setup.params), targets)
    # measured 134 of 143 (93.7 %) among 337 valid blobs (128, 89.5 %, with plain regions
    # before the growth from peaks): the crop alone (calmer than the whole frame) gives a
    # threshold of 4.6 where the camera's frames give 9.4 (OpenPTV: 9)
    assert score["found_1px"] >= 0.93 * len(targets), score
    assert score["valid_blobs"] <= 2.5 * len(targets), score


@pytest.mark.parametrize("name", ["cal1", "cal4", "target_cam1_crop"])
def test_dot_target_crops_keep_the_blob_route(name: str) -> None:
    setup = configure_detection([read_image(FIXTURES / f"{name}.png")])
    assert setup.params.route == "blobs", setup.choices["route"].why


def _field(rng: np.random.Generator, peaks: np.ndarray, sigmas: np.ndarray) -> np.ndarray:
    image = rng.normal(15, 1.0, (500, 500))
    grid = np.stack(np.meshgrid(np.arange(12, 490, 24), np.arange(12, 490, 24)), -1)
    for (x, y), peak, sigma in zip(grid.reshape(-1, 2), peaks, sigmas, strict=False):
        y0, x0 = int(y) - 10, int(x) - 10
        image[y0 : y0 + 21, x0 : x0 + 21] += _spot((21, 21), 10 + x % 1, 10, peak, sigma)
    return image.clip(0, 255).astype(np.uint8)


def test_a_crowd_of_one_size_is_a_target_and_of_every_size_particles() -> None:
    rng = np.random.default_rng(5)
    n = 400
    dots = _field(rng, np.full(n, 180.0), np.full(n, 1.3))
    assert configure_detection([dots]).params.route == "blobs"
    particles = _field(rng, rng.uniform(15, 200, n), rng.uniform(0.4, 1.1, n))
    setup = configure_detection([particles])
    assert setup.params.route == "peaks", setup.choices["route"].why
    assert setup.params.max_width_px is None and setup.params.max_pixels is not None
    fewer = configure_detection([particles], {"peak_min_spots": 100_000})  # the choice's own
    assert fewer.params.route == "blobs", fewer.choices["route"].why  # settings are honoured
