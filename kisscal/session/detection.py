"""``kisscal detect``: blobs of image files, with given, derived or a session camera's settings."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from kisscal.detect import Blobs, DetectionParams, detect_sequence
from kisscal.detect.configure import configure_detection
from kisscal.detect.pipeline import hopeless
from kisscal.errors import InputError
from kisscal.io.blobs import write_blobs
from kisscal.io.config import SessionConfig
from kisscal.io.files import write_bytes
from kisscal.io.frames import read_image
from kisscal.report.overlay import draw_overlay
from kisscal.session.inputs import select_cameras, writes_session
from kisscal.session.params import Overrides, stage_params
from kisscal.session.progress import Echo, quiet
from kisscal.session.runner import camera_detection


def detect_images(
    paths: Sequence[Path],
    out_csv: Path | None = None,
    overlay_dir: Path | None = None,
    detection: Mapping[str, Any] | None = None,
    echo: Echo = quiet,
    session: Path | None = None,
    camera: str | None = None,
    kind: str = "markers",
) -> list[tuple[str, Blobs]]:
    """``kisscal detect``: blobs of image files, to one CSV and overlays optionally.

    The settings are ``detection`` (given values) on top of, with ``session`` and
    ``camera``, that camera's derived settings (``out/detection/<camera>.json``), or else
    settings derived from these images themselves (up to 24 of them, spread evenly).
    What was used is echoed. Returns ``(image path as given, blobs)`` per image. Every
    image is read and checked before anything is written, so a bad file leaves earlier
    outputs untouched.
    """
    given = dict(detection or {})
    images = [read_image(p) for p in paths]
    if session is not None:
        params = _session_params(Path(session), camera, kind, given, echo)
    else:
        picks = np.unique(np.linspace(0, len(images) - 1, min(len(images), 24)).astype(int))
        setup = configure_detection([images[i] for i in picks], given, kind=kind)  # type: ignore[arg-type]
        echo(f"detection settings from {len(picks)} of these images: {setup.summary()}")
        params = setup.params
    blobs = detect_sequence(images, params)
    tables = [(str(p), b) for p, b in zip(paths, blobs, strict=True)]
    for p, image, b in zip(paths, images, blobs, strict=True):
        why = hopeless(image, params) if len(b) == 0 else None
        if why is not None:
            echo(f"{p}: {why}")
    if out_csv is not None:
        write_blobs(out_csv, tables)
    if overlay_dir is not None:
        _write_overlays(Path(overlay_dir), paths, images, blobs)
    total = sum(len(b) for b in blobs)
    valid = sum(int(b.valid.sum()) for b in blobs)
    echo(f"{len(paths)} images: {total} blobs ({valid} valid)")
    return tables


def _session_params(
    root: Path, camera: str | None, kind: str, given: Mapping[str, Any], echo: Echo
) -> DetectionParams:
    """A session camera's derived settings with ``given`` on top."""
    if camera is None:
        raise InputError("--session needs --camera: whose derived settings to use")

    @writes_session
    def derive(root: Path, config: SessionConfig) -> DetectionParams:
        cam = select_cameras(config, camera)[0]
        params = stage_params(config, Overrides(detection=given))
        return camera_detection(config, cam, kind, params, echo)

    detection = derive(root)
    echo(
        f"detection settings of camera {camera} ({kind} images of {root}): threshold "
        f"{detection.threshold:g}"
        + (" above the local background" if detection.background_tile_px else " (grey level)")
        + f", pixel aspect {detection.pixel_aspect:g}, oversize above "
        f"{detection.max_pixels} px"
    )
    return detection


def _write_overlays(
    folder: Path, paths: Sequence[Path], images: Sequence[np.ndarray], blobs: Sequence[Blobs]
) -> None:
    for k, (p, image, b) in enumerate(zip(paths, images, blobs, strict=True)):
        rgb = draw_overlay(image, b)
        _ok, buf = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        # numbered and with the folder: frames of different cameras share file names
        name = f"{k:04d}_{Path(p).parent.name}_{Path(p).stem}_overlay.png"
        write_bytes(folder / name, buf.tobytes())
