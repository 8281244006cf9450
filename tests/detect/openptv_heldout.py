"""Held-out check: default detection on any OpenPTV working folder's frames.

``python -m tests.detect.openptv_heldout DIR [DIR ...]`` scores kisscal's default
detection against the targets OpenPTV stored beside each frame (``camN.K`` with
``camN.K_targets``, OpenPTV's own detection with that experiment's settings), so that
real frames kisscal was never tuned on can be checked the same way as the cavity set
(:mod:`tests.detect.real_acceptance`). Settings are derived per camera from that
camera's frames in the folder, as ``kisscal detect`` derives them. One JSON line per
camera: targets, found by a valid blob within 1 px, valid blobs more than 1 px from
every target (extra), and with five frames in a row or more, both detections scored
against the particles tracked through them (:func:`tracked_scores`). Frames without a
targets file are skipped.
"""

from __future__ import annotations

import argparse
import json
import re
from collections import defaultdict
from pathlib import Path

import numpy as np

from kisscal.detect import detect_blobs
from kisscal.detect.configure import configure_detection
from kisscal.io.frames import read_image
from tests.detect.real_acceptance import score_targets, tracked_scores


def _frames(folder: Path) -> dict[str, list[Path]]:
    """Frames with an OpenPTV targets file beside them, by camera name."""
    cams: dict[str, list[Path]] = defaultdict(list)
    for path in sorted(folder.iterdir()):
        target = path.with_name(path.name + "_targets")
        match = re.fullmatch(r"(cam\d+)\.\d+", path.name)
        if match and target.is_file():
            cams[match.group(1)].append(path)
    return cams


def _targets(path: Path) -> np.ndarray:
    """OpenPTV's targets of a frame in kisscal's pixels (OpenPTV's origin is the corner)."""
    rows = np.loadtxt(path.with_name(path.name + "_targets"), skiprows=1, ndmin=2)
    return rows[:, 1:3] - 0.5


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="+", type=Path)
    args = parser.parse_args(argv)
    for folder in args.folders:
        for cam, paths in _frames(folder).items():
            images = [read_image(p) for p in paths]
            params = configure_detection(images).params
            total: dict = defaultdict(int)
            seen = []
            for path, image in zip(paths, images, strict=True):
                blobs, targets = detect_blobs(image, params), _targets(path)
                score = score_targets(blobs, targets)
                for key in ("targets", "found_1px", "valid_blobs", "extra"):
                    total[key] += score[key]
                seen.append((blobs.valid_only().xy_px, targets))
            total["recall_pct"] = round(100 * total["found_1px"] / max(total["targets"], 1), 1)
            numbers = [int(p.name.split(".")[-1]) for p in paths]
            if len(paths) >= 5 and np.all(np.diff(numbers) == 1):  # frames in a row
                total.update(tracked_scores(*(list(x) for x in zip(*seen, strict=True))))
            print(json.dumps({"folder": str(folder), "camera": cam, "frames": len(paths), **total}))


if __name__ == "__main__":
    main()
