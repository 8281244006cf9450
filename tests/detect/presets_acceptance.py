"""Self-configured detection on every rig preset, scored against the rig's truth.

``python -m tests.detect.presets_acceptance [--fields N] PRESET:SEED ...`` renders each rig
in memory, derives every camera's detection settings as a session does (grid frames on
their own, pixel aspect from the grid lattice, marker settings from a sample of rod and
trial frames; :mod:`kisscal.session.configure`), detects every trial field and prints per
rig: the derived pixel aspect against the truth, whether the derived size band holds
every true marker and stops the LED rings, and recall, precision and centroid RMS on the
trial's isolated markers (the rules of ``tests/detect/test_rig.py``).
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass, field

import numpy as np

from kisscal.detect import DetectionParams, detect_blobs
from kisscal.detect.configure import configure_detection
from kisscal.grid.frames import dots_from_frames
from kisscal.grid.lattice import lattice_pixel_aspect
from kisscal.session.configure import LATTICE_SQUARE_TOLERANCE
from kisscal.synth.plan import plan_session, render_grid, render_rods, render_trial
from kisscal.synth.presets import synth_options
from kisscal.synth.truth import camera_detection_truth
from tests.detect.test_rig import Score


@dataclass
class CameraResult:
    camera: str
    aspect_true: float
    aspect_derived: float
    band_holds_markers: bool
    band_stops_leds: bool
    max_pixels: int | None
    true_marker_pixels_max: float
    led_pixels_min: float | None


@dataclass
class RigResult:
    preset: str
    seed: int
    cameras: list[CameraResult] = field(default_factory=list)
    score: Score = field(default_factory=Score)

    def line(self) -> dict:
        aspect_err = max(abs(c.aspect_derived / c.aspect_true - 1) for c in self.cameras)
        return {
            "preset": self.preset,
            "seed": self.seed,
            "aspect_err_max_pct": round(100 * aspect_err, 2),
            "band_holds_every_marker": all(c.band_holds_markers for c in self.cameras),
            "band_stops_leds": all(c.band_stops_leds for c in self.cameras),
            "recall_pct": round(100 * self.score.recall, 3),
            "precision_pct": round(100 * self.score.precision, 3),
            "isolated_rms_px": round(self.score.isolated_rms_px, 4),
            "markers": self.score.markers,
        }


def camera_settings(plan, cam: int, trial_frames: list[np.ndarray]) -> DetectionParams:
    """The camera's marker settings, derived as :mod:`kisscal.session.configure` does."""
    grid_frames, _ = render_grid(plan, cam)
    grid = configure_detection(grid_frames, kind="grid", pixel_aspect=1.0)
    aspect = lattice_pixel_aspect(dots_from_frames(grid_frames, grid.params))
    aspect = 1.0 if abs(aspect - 1.0) <= LATTICE_SQUARE_TOLERANCE else aspect
    rods, _, _ = render_rods(plan, cam)
    sample = rods + trial_frames[:: max(1, len(trial_frames) // 16)]
    return configure_detection(sample, pixel_aspect=aspect, aspect_why="grid lattice").params


def _largest_marker_pixels(truths) -> float:
    """White pixels, at a tenth of the plateau, of the largest whole marker seen."""
    pixels = np.concatenate([t.sizes["low"].pixels for t in truths if "low" in t.sizes])
    pixels = pixels[np.isfinite(pixels)]
    return float(pixels.max()) if pixels.size else 0.0


def measure(preset: str, seed: int, fields: int) -> RigResult:
    options = synth_options(preset, seed, fields=fields)
    plan = plan_session(options)
    result = RigResult(preset, seed)
    for cam in range(len(plan.rig)):
        rendered = list(render_trial(plan, "walk01", cam))
        frames = [r[1] for r in rendered]
        truths = [r[2] for r in rendered]
        params = camera_settings(plan, cam, frames)
        truth = camera_detection_truth(plan, cam, {})
        px = _largest_marker_pixels(truths)
        leds = truth["led_rings"]["half"]["pixels"] if truth["led_rings"]["whole"] else None
        limit = params.max_pixels
        result.cameras.append(
            CameraResult(
                plan.rig[cam].id,
                float(truth["pixel_aspect"]),
                float(params.pixel_aspect),
                limit is None or px <= limit,
                leds is None or (limit is not None and leds[0] > limit),
                limit,
                px,
                None if leds is None else float(leds[0]),
            )
        )
        for image, t in zip(frames, truths, strict=True):
            v = t.visible
            result.score.add(detect_blobs(image, params), t.uv_px[v], t.radii_px[v], t.isolated[v])
    return result


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("rigs", nargs="+", help="PRESET:SEED, e.g. modern:21")
    parser.add_argument("--fields", type=int, default=40)
    args = parser.parse_args(argv)
    for rig in args.rigs:
        preset, seed = rig.split(":")
        print(json.dumps(measure(preset, int(seed), args.fields).line()), flush=True)


if __name__ == "__main__":
    main()
