"""Camera frames on disk: frame folders (PNG/TIFF/BMP) and videos, read lazily.

A trial is never held in memory whole: :class:`FrameFiles` and :class:`VideoFrames`
read one frame when it is indexed; a video is decoded in order by one reader per process
(detection workers take runs of consecutive frames). :class:`Fields` splits interlaced
frames into their two fields.
"""

from __future__ import annotations

import contextlib
import contextvars
import os
import struct
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from kisscal.errors import InputError, MissingDataError

IMAGE_SUFFIXES = {".png", ".tif", ".tiff", ".bmp"}
VIDEO_SUFFIXES = {".avi", ".mp4", ".mov", ".mkv", ".mpg", ".mpeg", ".m4v", ".wmv"}

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
    try:  # no stat first: the open says it (a stat per frame, thousands a run)
        data = np.fromfile(path, dtype=np.uint8)
    except (FileNotFoundError, IsADirectoryError):
        raise MissingDataError(f"{path}: image file not found") from None
    image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if image is None:
        raise InputError(f"{path}: not a readable image (corrupt or unsupported format)")
    if image.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        image = cv2.cvtColor(image, code)
    if image.dtype not in (np.uint8, np.uint16):
        raise InputError(f"{path}: unsupported pixel type {image.dtype}; expected 8 or 16 bit")
    return image


#: First bytes of the image formats kisscal reads (PNG, TIFF either byte order, BMP): a
#: file without one of the suffixes above is a frame when it starts with one of these.
IMAGE_SIGNATURES = (b"\x89PNG\r\n\x1a\n", b"II*\x00", b"MM\x00*", b"BM")


def is_image_file(path: Path) -> bool:
    """True for a frame file: an image suffix, or any other name whose content starts
    like a PNG, TIFF or BMP image (numbered frames such as ``cam1.10000``)."""
    path = path if isinstance(path, Path) else Path(path)  # not rebuilt: thousands a run
    suffix = path.suffix.lower()
    if suffix in IMAGE_SUFFIXES:
        return True
    if suffix in VIDEO_SUFFIXES or not path.is_file():
        return False
    with open(path, "rb") as f:
        head = f.read(8)
    return head.startswith(IMAGE_SIGNATURES)


@dataclass(frozen=True)
class ImageHeader:
    """What an image file's header says, read without decoding its pixels."""

    size: tuple[int, int]  # width, height in pixels
    format: str  # the format of the data ("PNG", "JPEG", ...), whatever the file's name


#: Formats whose compression changes pixel values (and so moves centroids).
LOSSY_FORMATS = frozenset({"JPEG", "MPO"})


def image_header(path: Path) -> ImageHeader:
    """Size and data format of an image file, from its header only (cheap: no decoding).

    PNG (the usual frame format) is read from its first 24 bytes; other formats by Pillow,
    which also reads only the header.
    """
    from PIL import Image, UnidentifiedImageError

    try:
        with open(path, "rb") as file:
            head = file.read(24)
        if head[:8] == IMAGE_SIGNATURES[0] and head[12:16] == b"IHDR":
            w, h = struct.unpack(">II", head[16:24])
            return ImageHeader((int(w), int(h)), "PNG")
        with Image.open(path) as image:
            return ImageHeader((int(image.width), int(image.height)), str(image.format))
    except FileNotFoundError:
        raise MissingDataError(f"{path}: file not found") from None
    except (UnidentifiedImageError, OSError, ValueError):
        raise InputError(f"{path}: not a readable image") from None


def _glob(root: Path, pattern: str) -> list[Path]:
    """Files matching ``pattern``, relative to ``root`` or absolute."""
    if Path(pattern).is_absolute():  # Path.glob takes relative patterns only
        anchor = Path(Path(pattern).anchor)
        return list(anchor.glob(str(Path(pattern).relative_to(anchor))))
    return list(Path(root).glob(pattern))


#: Frame listings kept inside :func:`listing_once` (None: none kept).
_LISTED: contextvars.ContextVar[dict[tuple[str, str], list[Path]] | None] = contextvars.ContextVar(
    "kisscal_listed", default=None
)


@contextlib.contextmanager
def listing_once() -> Iterator[None]:
    """Inside the block, each camera's frames are listed once (:func:`frame_paths`): a
    session command's inputs do not change while it runs, and ``kisscal run`` listed the
    same folders some 300 times (validation, surveys, cache keys, detection)."""
    token = _LISTED.set({} if _LISTED.get() is None else _LISTED.get())
    try:
        yield
    finally:
        _LISTED.reset(token)


def frame_paths(root: Path, pattern: str, camera: str, what: str) -> list[Path]:
    """Sorted frame files of ``camera`` matching ``pattern`` (``{camera}`` substituted;
    relative to ``root``, or absolute); listed once inside :func:`listing_once`.

    A file is a frame by its suffix (PNG, TIFF, BMP) or, without one, by its content; when
    none is found the message names the files the pattern matched, or those beside it.
    """
    glob = pattern.replace("{camera}", camera)
    listed = _LISTED.get()
    key = (str(root), glob)
    if listed is not None and key in listed:
        return list(listed[key])
    matched = sorted(p for p in _glob(root, glob) if p.is_file())
    paths = [p for p in matched if is_image_file(p)]
    if not paths:
        raise MissingDataError(
            f"{Path(root) / glob}: no {what} images for camera {camera}; "
            + _what_is_there(Path(root), glob, matched)
        )
    if listed is not None:
        listed[key] = paths
    return list(paths)


def _what_is_there(root: Path, glob: str, matched: list[Path]) -> str:
    """The files a pattern matched (none an image), or those in the folder it looks in."""
    if matched:
        return f"it matches {_names(matched, root)}, none a PNG, TIFF or BMP image"
    parts = Path(glob).parts
    fixed = next((i for i, p in enumerate(parts) if any(c in p for c in "*?[")), len(parts) - 1)
    folder = root.joinpath(*parts[:fixed])
    if not folder.is_dir():
        return f"there is no folder {folder}"
    beside = sorted(p for p in folder.iterdir() if p.is_file())
    if not beside:
        return f"{folder} holds no files"
    return (
        f"the pattern misses every file of {folder}: {_names(beside, folder)} "
        '(frames without a suffix are read by content: write e.g. "{camera}.*")'
    )


def _names(paths: list[Path], root: Path, shown: int = 5) -> str:
    """The first few file names (relative to ``root``) and how many there are."""
    names = [p.relative_to(root).as_posix() if p.is_relative_to(root) else str(p) for p in paths]
    more = f" ... ({len(names)} files)" if len(names) > shown else ""
    return ", ".join(names[:shown]) + more


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


class _Reader:
    """One open ``cv2.VideoCapture`` and where it stands, for sequential decoding."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.cap = cv2.VideoCapture(str(path))
        if not self.cap.isOpened():
            raise InputError(f"{path}: not a readable video")
        self.count = int(self.cap.get(cv2.CAP_PROP_FRAME_COUNT))
        self.next = 0  # index of the frame the next read() returns
        self.last: tuple[int, np.ndarray] | None = None

    def frame(self, index: int) -> np.ndarray:
        if self.last is not None and self.last[0] == index:
            return self.last[1]  # the second field of an interlaced frame
        if not self.next <= index < self.next + SKIP_FORWARD_FRAMES:
            self.cap.set(cv2.CAP_PROP_POS_FRAMES, int(index))
            self.next = int(self.cap.get(cv2.CAP_PROP_POS_FRAMES))
            if self.next != index:  # a backend that cannot seek exactly: from the start
                self.cap.release()
                self.__init__(self.path)  # type: ignore[misc]
        while self.next < index:
            self.cap.grab()
            self.next += 1
        ok, frame = self.cap.read()
        if not ok:
            raise InputError(f"{self.path}: frame {index} cannot be decoded (truncated video?)")
        self.next = index + 1
        gray = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame
        self.last = (index, gray)
        return gray


#: Frames a reader decodes and drops to move forward instead of seeking.
SKIP_FORWARD_FRAMES = 64
# One reader per process and video: forked detection workers each open their own.
_READERS: dict[tuple[int, Path], _Reader] = {}


def close_readers() -> None:
    """Release this process's open video readers: call before forking workers (a decoder's
    threads do not survive a fork; each worker opens its own reader)."""
    for reader in _READERS.values():
        reader.cap.release()
    _READERS.clear()


# A decoder's threads do not survive a fork (a child could wait forever on a lock one of
# them held): every fork of this process first releases its readers.
os.register_at_fork(before=close_readers)


def _reader(path: Path) -> _Reader:
    key = (os.getpid(), Path(path))
    if key not in _READERS:
        if any(pid == os.getpid() for pid, _ in _READERS):
            close_readers()  # one video at a time per process
        _READERS.clear()  # readers inherited from a parent process are not ours to use
        _READERS[key] = _Reader(Path(path))
    return _READERS[key]


@dataclass(frozen=True)
class VideoFrames(Sequence):
    """Frames of a video file, decoded in order by one reader per process.

    Indexing frames in increasing order decodes each frame once (a jump back, or far
    forward, seeks); the reader stays open between calls, so a trial is never decoded
    frame by frame from a fresh file, and never held in memory.
    """

    path: Path
    #: Decoding is cheapest in order: readers should take runs of consecutive frames.
    sequential = True

    def __len__(self) -> int:
        return _reader(self.path).count

    def __getitem__(self, index):  # type: ignore[override]
        if isinstance(index, slice):
            raise TypeError("video frames are indexed one at a time")
        reader = _reader(self.path)
        if not 0 <= index < reader.count:
            raise IndexError(f"{self.path}: no frame {index}")
        return reader.frame(int(index))


@dataclass(frozen=True)
class Fields(Sequence):
    """The fields of interlaced frames: frame ``k`` gives fields ``2k`` and ``2k + 1``.

    ``order`` says which field was exposed first: ``"top-first"`` (the even rows 0, 2, 4,
    ... are field ``2k``) or ``"bottom-first"``. A field has half the frame's rows (the
    pixels become twice as tall as wide; the DLT absorbs that).
    """

    frames: Sequence[np.ndarray]
    order: str

    def __len__(self) -> int:
        return 2 * len(self.frames)

    def __getitem__(self, index):  # type: ignore[override]
        frame = self.frames[index // 2]
        first = 0 if self.order == "top-first" else 1
        return np.ascontiguousarray(frame[(first + index % 2) % 2 :: 2])

    @property
    def sequential(self) -> bool:
        return bool(getattr(self.frames, "sequential", False))

    def name(self, index: int) -> str:
        """Where field ``index`` comes from, for messages."""
        return f"{frame_name(self.frames, index // 2)} field {index % 2 + 1}"


def camera_frames(
    root: Path, pattern: str, camera: str, what: str, video: bool = False, fields: str | None = None
) -> Sequence:
    """The frames of one camera, as a lazy sequence: image files, or one video (``video``,
    or a pattern ending in a video suffix); with ``fields``, split into fields."""
    if video or Path(pattern).suffix.lower() in VIDEO_SUFFIXES:
        path = Path(root) / pattern.replace("{camera}", camera)
        if not path.is_file():
            raise MissingDataError(f"{path}: {what} video for camera {camera} not found")
        frames: Sequence = VideoFrames(path)
    else:
        frames = FrameFiles(tuple(frame_paths(root, pattern, camera, what)))
    return Fields(frames, fields) if fields else frames


def source_files(frames: Sequence) -> list[Path]:
    """The files a camera's frames come from (image files, or the one video)."""
    if isinstance(frames, Fields):
        return source_files(frames.frames)
    paths = getattr(frames, "paths", None)
    return list(paths) if paths is not None else [Path(frames.path)]  # type: ignore[attr-defined]


def frame_name(frames: Sequence, index: int) -> str:
    """Where frame ``index`` of a camera's frames comes from, for messages."""
    if isinstance(frames, Fields):
        return frames.name(index)
    if isinstance(frames, FrameFiles):
        return str(frames.paths[index])
    return f"{getattr(frames, 'path', '')} frame {index}".strip()


def trial_frames(
    root: Path,
    pattern: str,
    cameras: Sequence[str],
    trial: str,
    video: bool = False,
    fields: str | None = None,
) -> dict[str, Sequence]:
    """Frames of every camera of a trial; unequal frame counts are an error."""
    frames = {
        c: camera_frames(root, pattern, c, f"trial {trial!r}", video, fields) for c in cameras
    }
    counts = {c: len(f) for c, f in frames.items()}
    if len(set(counts.values())) > 1:
        detail = ", ".join(f"{c}: {n}" for c, n in counts.items())
        raise InputError(f"trial {trial!r}: cameras have different numbers of frames ({detail})")
    return frames
