"""What a camera's detection settings are derived from: the frames sampled for its survey
and, for its grid frames, the pixel aspect of the grid's dot lattice.

For each camera, a few frames of each of its image sets are surveyed
(:func:`kisscal.detect.configure.configure_detection`): its grid frames on their own
(``grid``) and everything else together (``markers``: rods, axes, calibration target,
trials), the cameras' marker images side by side in the detector's pool
(:func:`kisscal.detect.sequence.surveyed`). The camera's pixel aspect comes from
its grid lattice when there is a grid (:func:`kisscal.grid.lattice.lattice_pixel_aspect`,
exact to a fraction of a percent), otherwise from the shape of its markers. What
``[detection]`` (or the command line) gives is used as given: it comes typed from the
session's resolved parameters (:func:`kisscal.session.params.stage_params`), never from
the raw table. The result, with the reason for every value, is written to
``out/detection/<camera>.json`` and kept: the settings are a property of the camera.
The running session uses the settings it derived in memory; the file is read only to
find settings an earlier run derived. The runner (:mod:`kisscal.session.runner`) keeps
the records and runs the surveys.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from kisscal.detect.configure import Choice, DetectionSetup, configure_detection
from kisscal.errors import KisscalError
from kisscal.grid.frames import dots_from_frames
from kisscal.grid.lattice import lattice_pixel_aspect
from kisscal.io.config import CameraConfig, SessionConfig
from kisscal.io.frames import camera_frames
from kisscal.session.inputs import image_sources
from kisscal.session.params import StageParams
from kisscal.session.trials import SizedFrames

#: Frames surveyed per image set (spread evenly over it) and per camera and kind at most.
FRAMES_PER_SET = 8
MAX_FRAMES = 24
#: A lattice aspect this close to 1 is square pixels (a grid 14 degrees off face-on).
LATTICE_SQUARE_TOLERANCE = 0.03


@dataclasses.dataclass(frozen=True)
class Sample:
    """Frames of one camera and kind picked for the survey (decoded only when needed)."""

    picks: tuple[tuple[Sequence, int], ...]  # (a set of frames, an index picked in it)
    camera: CameraConfig

    def frame(self, k: int) -> np.ndarray:
        """Picked frame ``k``, decoded and checked for the camera's size."""
        seq, i = self.picks[k]
        return SizedFrames(seq, self.camera.id, self.camera.size_px)[i]

    @property
    def frames(self) -> list[np.ndarray]:
        return [self.frame(k) for k in range(len(self.picks))]


def grid_setup(sample: Sample, params: StageParams) -> DetectionSetup:
    """Settings of a camera's grid frames, with its pixel aspect from the dot lattice.

    Only a pixel aspect measured on the lattice is recorded as ``derived``; without a
    lattice the grid frames are detected with square pixels, recorded as ``default``, and
    the camera's marker images measure its aspect themselves.
    """

    frames, given = sample.frames, params.detection_given
    why = "grid dots: never split"
    setup = configure_detection(frames, given, kind="grid", pixel_aspect=1.0, aspect_why=why)
    if "pixel_aspect" in given:
        return setup
    try:
        aspect = lattice_pixel_aspect(
            dots_from_frames(frames, setup.params), params.grid.cell_aspect
        )
    except KisscalError:  # no lattice in these frames: the markers will tell
        why = "no dot lattice in the grid frames: square pixels assumed for them"
        choices = {**setup.choices, "pixel_aspect": Choice(1.0, "default", why)}
        return dataclasses.replace(setup, choices=choices)
    # a grid tilted by t reads the aspect off by up to 1 - cos t: within 3 % it is square
    aspect = 1.0 if abs(aspect - 1.0) <= LATTICE_SQUARE_TOLERANCE else round(aspect, 4)
    return _with_lattice_aspect(setup, aspect)


def _with_lattice_aspect(setup: DetectionSetup, aspect: float) -> DetectionSetup:
    """``setup`` with the camera's pixel aspect measured on its grid lattice."""
    choices = dict(setup.choices)
    why = "x over y step of the grid's dot lattice"
    choices["pixel_aspect"] = Choice(aspect, "derived", why)
    params = setup.params.replace(pixel_aspect=aspect)
    return dataclasses.replace(setup, params=params, choices=choices)


def survey_sample(config: SessionConfig, camera: CameraConfig, kind: str) -> Sample | None:
    """Up to :data:`MAX_FRAMES` frames of the camera's ``kind`` images, spread evenly."""
    # a known target's photographs (dots on a lit plate) are not marker images
    sources = [
        src
        for src in image_sources(config)
        if (src[0] == "grid") == (kind == "grid") and src[0] != "calibration"
    ]
    picks: list[tuple[Sequence, int]] = []
    per_set = min(max(MAX_FRAMES // max(len(sources), 1), 3), FRAMES_PER_SET)
    for what, pattern, video, fields in sources:
        try:
            seq = camera_frames(config.root, pattern, camera.id, what, video, fields)
        except KisscalError:
            continue  # missing frames are reported by the stage that needs them
        n = len(seq)
        picked = np.unique(np.linspace(0, n - 1, min(n, per_set)).astype(int))
        picks += [(seq, int(i)) for i in picked]
    return Sample(tuple(picks), camera) if picks else None
