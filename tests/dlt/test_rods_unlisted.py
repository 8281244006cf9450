"""A rod hanging in the images but missing from [[rods.rod]] is refused, never ignored."""

from __future__ import annotations

import numpy as np
import pytest

from kisscal.dlt import DltParams, Rod, calibrate_rods, recognise_rods
from kisscal.errors import KisscalError
from tests.dlt.acceptance import rod_images


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("dropped", range(4))
def test_a_rod_left_out_of_the_config_is_refused_in_every_camera(seed, dropped):
    imgs = rod_images(seed, hide=False)
    rods = tuple(r for i, r in enumerate(imgs.rods) if i != dropped)
    for cam, blobs, truth in zip(imgs.cameras, imgs.blobs, imgs.truth, strict=True):
        mine = truth.reshape(4, 6)[dropped]
        assert (mine >= 0).sum() >= DltParams().rod_min_markers  # the camera sees that rod
        with pytest.raises(KisscalError, match=r"match no rod in \[\[rods\.rod\]\]") as err:
            recognise_rods(blobs, rods, camera=cam.id)
        msg = str(err.value)
        assert "\n" not in msg and msg.startswith(f"camera {cam.id}: ")
        # All six markers counted (a stray blob may happen to lie on the same line), and the
        # position named is the dropped rod's (mean u of its markers, px).
        n = int(msg.split(": ")[1].split(" blobs")[0])
        u = float(msg.split("u=")[1].split(" px")[0])
        assert n in (6, 7)
        assert abs(u - blobs[mine, 0].mean()) < 3.0, (n, u, blobs[mine, 0].mean())


@pytest.mark.parametrize("seed", range(20))
def test_no_false_alarm_from_led_rings_and_noise(seed):
    # All four rods listed, the LED rings of the facing cameras, 12 noise blobs per image
    # and one hidden rod marker: nothing left over may pass for a rod.
    imgs = rod_images(seed, hide=True, n_noise=12)
    for cam, blobs, truth in zip(imgs.cameras, imgs.blobs, imgs.truth, strict=True):
        match = recognise_rods(blobs, imgs.rods, camera=cam.id)
        np.testing.assert_array_equal(match.blob_index.ravel(), truth, err_msg=cam.id)


def test_the_switch_allows_extra_rods():
    imgs = rod_images(3, hide=False)
    rods = imgs.rods[:3]
    params = DltParams(rod_refuse_unlisted=False)
    for cam, blobs, truth in zip(imgs.cameras, imgs.blobs, imgs.truth, strict=True):
        match = recognise_rods(blobs, rods, params, camera=cam.id)
        np.testing.assert_array_equal(match.blob_index.ravel(), truth[:18], err_msg=cam.id)
        assert set(truth[18:]) <= set(match.unused_blobs.tolist())


def test_calibrate_rods_refuses_before_calibrating():
    imgs = rod_images(1, hide=False)
    blobs = {c.id: b for c, b in zip(imgs.cameras, imgs.blobs, strict=True)}
    with pytest.raises(KisscalError, match=r"camera cam1: .*is a rod missing from session\.toml"):
        calibrate_rods(blobs, imgs.rods[1:])


def test_an_unrecognised_listed_rod_is_named():
    # R4 hangs but is not listed; a rod R5 with paired markers (1900, 1850, 1000, 950, 150,
    # 100 mm) is listed but hangs nowhere: the message names R5 as a suspect too.
    imgs = rod_images(2, hide=False)
    points = imgs.rods[3].points_mm.copy()
    points[:, 2] = [1900, 1850, 1000, 950, 150, 100]
    rods = (*imgs.rods[:3], Rod(name="R5", points_mm=points))
    for cam, blobs in zip(imgs.cameras, imgs.blobs, strict=True):
        with pytest.raises(
            KisscalError, match=r"missing from session\.toml, or are points_mm of R5"
        ):
            recognise_rods(blobs, rods, camera=cam.id)
