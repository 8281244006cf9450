"""Camera frames on disk: frame folders (PNG/TIFF/BMP) and videos, read lazily.

A trial is never held in memory whole: :class:`FrameFiles` and :class:`VideoFrames`
read one frame when it is indexed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from kisscal.errors import KisscalError

IMAGE_SUFFIXES = {".png", ".tif", ".tiff", ".bmp"}

# OpenCV prints its own warnings for corrupt files; kisscal reports them in one line.
try:
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
except AttributeError:  # pragma: no cover - builds without the logging module
    pass


def read_image(path: Path) -> np.ndarray:
    """One grayscale frame (8 or 16 bit) from an image file.

    Colour images are converted to grayscale; unreadable or corrupt files raise a
    :class:`KisscalError` naming the file.
    """
    path = Path(path)
    if not path.is_file():
        raise KisscalError(f"{path}: image file not found")
    data = np.fromfile(path, dtype=np.uint8)
    image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if image is None:
        raise KisscalError(f"{path}: not a readable image (corrupt or unsupported format)")
    if image.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        image = cv2.cvtColor(image, code)
    if image.dtype not in (np.uint8, np.uint16):
        raise KisscalError(f"{path}: unsupported pixel type {image.dtype}; expected 8 or 16 bit")
    return image


def frame_paths(root: Path, pattern: str, camera: str, what: str) -> list[Path]:
    """Sorted frame files of ``camera`` matching ``pattern`` (``{camera}`` substituted)."""
    glob = pattern.replace("{camera}", camera)
    paths = sorted(p for p in Path(root).glob(glob) if p.suffix.lower() in IMAGE_SUFFIXES)
    if not paths:
        raise KisscalError(f"{Path(root) / glob}: no {what} images for camera {camera}")
    return paths


@dataclass(frozen=True)
class FrameFiles(Sequence):
    """Frames stored as one image file each, loaded when indexed."""

    paths: tuple[Path, ...]

    def __len__(self) -> int:
        return len(self.paths)

    def __getitem__(self, index):  # type: ignore[override]
        if isinstance(index, slice):
            return FrameFiles(self.paths[index])
        return read_image(self.paths[index])


@dataclass(frozen=True)
class VideoFrames(Sequence):
    """Frames of a video file, decoded when indexed (sequential access is fastest)."""

    path: Path

    def __len__(self) -> int:
        cap = cv2.VideoCapture(str(self.path))
        try:
            if not cap.isOpened():
                raise KisscalError(f"{self.path}: not a readable video")
            return int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        finally:
            cap.release()

    def __getitem__(self, index):  # type: ignore[override]
        if isinstance(index, slice):
            raise TypeError("video frames are indexed one at a time")
        cap = cv2.VideoCapture(str(self.path))
        try:
            cap.set(cv2.CAP_PROP_POS_FRAMES, int(index))
            ok, frame = cap.read()
        finally:
            cap.release()
        if not ok:
            raise KisscalError(f"{self.path}: frame {index} cannot be decoded (truncated video?)")
        return cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame


def camera_frames(
    root: Path, pattern: str, camera: str, what: str, video: bool = False
) -> Sequence:
    """The frames of one camera, as a lazy sequence."""
    if video:
        path = Path(root) / pattern.replace("{camera}", camera)
        if not path.is_file():
            raise KisscalError(f"{path}: {what} video for camera {camera} not found")
        return VideoFrames(path)
    return FrameFiles(tuple(frame_paths(root, pattern, camera, what)))


def trial_frames(
    root: Path, pattern: str, cameras: Sequence[str], trial: str, video: bool = False
) -> dict[str, Sequence]:
    """Frames of every camera of a trial; unequal frame counts are an error."""
    frames = {c: camera_frames(root, pattern, c, f"trial {trial!r}", video) for c in cameras}
    counts = {c: len(f) for c, f in frames.items()}
    if len(set(counts.values())) > 1:
        detail = ", ".join(f"{c}: {n}" for c, n in counts.items())
        raise KisscalError(f"trial {trial!r}: cameras have different numbers of frames ({detail})")
    return frames
