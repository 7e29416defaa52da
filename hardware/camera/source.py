"""Frame sources for the tactile camera: a device index, a video file or an image sequence.

``open_source`` returns the ``cv2.VideoCapture`` for any of the three; ``FrameReader``
iterates grey 8-bit frames from it and keeps the account of bad frames: a frame that
cannot be decoded, a frame of another size than the first, frames missing at the end of a
truncated video, and a frame with a frozen tile. Each bad frame is logged (WARNING) and
recorded, never yielded.

Frozen tiles: FFmpeg conceals a corrupt slice by copying it from the previous frame and
reports success, so a corrupt video decodes into plausible frames whose areas are wrong.
A live sensor's frames always carry shot noise, so a 16×16 tile that is bit-identical to
the previous frame's and not uniform (clipped black tiles are legitimately equal) marks
the frame as bad. Pass ``reject_frozen=False`` for noise-free synthetic video.

The check needs a source that stores every pixel: lossless video (FFV1, HuffYUV, PNG in
AVI, raw pixel formats) or PNG/TIFF/BMP images. A lossy encoder rounds the shot noise of
an unchanged region away and repeats its tiles exactly on purpose: 38 of 40 frames of a
noisy sensor recording in mp4v, XVID or MJPG were rejected as frozen. Any source not known
to keep every pixel (those three, H.264, JPEG files, ...) is read with the check off, and a
:class:`LossyVideoWarning` says so once (its areas also carry the compression error).

Image sequences (a printf pattern such as ``frames/%05d.png``) are read file by file with
``cv2.imread`` rather than through OpenCV's image-sequence backend, because that backend
stops silently at the first unreadable file and loses every frame after it.
"""
from __future__ import annotations

import logging
import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import os
import warnings

# libav's own log (e.g. '[ffv1 @ 0x55...] slice CRC mismatch' on a damaged frame) off stderr:
# damaged frames are named by feeler's own checks, counted and never used. Read by OpenCV when
# its ffmpeg backend starts, at the first capture; a user may set it to debug a source.
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")

import cv2  # noqa: E402
import numpy as np

from feeler.errors import ArgumentError, DataFileError

__all__ = ["open_source", "FrameReader", "write_video", "lossy_codec", "LossyVideoWarning"]

log = logging.getLogger(__name__)

_PATTERN = re.compile(r"%0?\d*d")
_TILE_PX = 16


#: video codecs and camera pixel formats that keep every pixel (FourCC, as OpenCV reports it)
LOSSLESS_FOURCC = frozenset({"FFV1", "FFVH", "HFYU", "MPNG", "PNG ", "png ", "ZLIB", "LAGS", "Y800", "GREY",
                             "Y8  ", "Y16 ", "YUYV", "YUY2", "UYVY", "I420", "IYUV", "YV12", "NV12", "RGB ",
                             "BGR ", "RGB3", "BGR3", "RGBA", "BGRA", "RAW ", "DIB "})
LOSSLESS_IMAGES = frozenset({".png", ".tif", ".tiff", ".bmp", ".pgm", ".ppm", ".pnm"})


class LossyVideoWarning(UserWarning):
    """A source in a lossy codec: the frozen-tile check is off, areas carry its error."""


def lossy_codec(src, cap: cv2.VideoCapture | None = None) -> str | None:
    """The name of the lossy codec of a source (``"mp4v"``, ``"MJPG"``, ``"JPEG images"``),
    or None when it stores every pixel (or says nothing: a FourCC of 0 is raw video)."""
    text = str(src)
    if not _is_device(src) and _PATTERN.search(text):
        suffix = Path(text).suffix.lower()
        return None if suffix in LOSSLESS_IMAGES else f"{suffix.lstrip('.').upper() or 'unknown'} images"
    if cap is None:
        return None
    code = int(cap.get(cv2.CAP_PROP_FOURCC)) & 0xFFFFFFFF
    if code == 0:
        return None
    name = "".join(chr((code >> 8 * k) & 0xFF) for k in range(4))
    return None if name in LOSSLESS_FOURCC or name.upper() in LOSSLESS_FOURCC else name.strip("\x00 ") or None


def lossy_warning(name: str, codec: str) -> None:
    """The one line a user sees for a lossy source (``warnings``: the CLI prints it once)."""
    warnings.warn(f"{name}: recorded in a lossy codec ({codec}): the check for frozen tiles is off (a lossy "
                  f"encoder repeats unchanged tiles exactly), and the contact areas carry the compression error; "
                  f"record in a lossless codec (FFV1, HuffYUV) or PNG images for the sensor's own accuracy",
                  LossyVideoWarning, stacklevel=3)


def _is_device(src) -> bool:
    return isinstance(src, int) or (isinstance(src, str) and src.isdigit())


@contextmanager
def _opencv_silent():
    """OpenCV's own log lines off while a source opens: a missing device index printed
    '[ WARN:0@0.018] global cap_ffmpeg_impl.hpp:1246 open VIDEOIO/FFMPEG: ...' ahead of the
    one-line error, which says what the user needs (``isOpened`` is checked instead)."""
    from cv2.utils import logging as cvlog

    level = cvlog.getLogLevel()
    cvlog.setLogLevel(cvlog.LOG_LEVEL_SILENT)
    try:
        yield
    finally:
        cvlog.setLogLevel(level)


def open_source(src: int | str | Path) -> cv2.VideoCapture:
    """Open a camera device index, a video file or an image-sequence pattern.

    Raises:
        DataFileError: no device at that index, a missing file, a file (or the first file
            of a sequence) that OpenCV cannot decode — one line naming the source.
    """
    if _is_device(src):
        with _opencv_silent():
            cap = cv2.VideoCapture(int(src))
        if not cap.isOpened():
            raise DataFileError(f"camera {int(src)}", "no camera device at this index")
        return cap
    text = str(src)
    if _PATTERN.search(text):
        first = _sequence_files(text)
        if not first:
            raise DataFileError(text, "image sequence has no files matching the pattern")
        with _opencv_silent():
            cap = cv2.VideoCapture(text, cv2.CAP_IMAGES)
    else:
        if not Path(text).is_file():
            raise DataFileError(text, "no such video file")
        with _opencv_silent():
            cap = cv2.VideoCapture(text)
    if not cap.isOpened():
        raise DataFileError(text, "cannot be opened as a video or image sequence (corrupt?)")
    return cap


class FrameReader:
    """Iterate the good grey frames of a source as ``(index, frame uint8[h, w])``.

    Args:
        src: device index, video file or image-sequence pattern.
        size (tuple[int, int] | None): expected (width_px, height_px); a first frame of
            another size raises :class:`DataFileError` naming the source.
        reject_frozen (bool): reject frames with a tile frozen from the previous frame
            (lossless sources only: off, with a :class:`LossyVideoWarning`, for a lossy one).

    Attributes:
        codec (str | None): the source's lossy codec, None when it keeps every pixel.

    Attributes after iteration:
        n_frames (int): frames attempted (good + bad, including missing ones).
        bad (list[tuple[int, str]]): (frame index, reason) of every bad frame.
    """

    def __init__(self, src: int | str | Path, *, size: tuple[int, int] | None = None,
                 reject_frozen: bool = True):
        self.src, self.size, self.reject_frozen = src, size, reject_frozen
        self.name = f"camera {int(src)}" if _is_device(src) else str(src)
        self.n_frames = 0
        self.bad: list[tuple[int, str]] = []
        if not _is_device(src) and _PATTERN.search(str(src)):
            self._files = _sequence_files(str(src))
            if not self._files:
                raise DataFileError(self.name, "image sequence has no files matching the pattern")
            self._cap = None
        else:
            self._files = None
            self._cap = open_source(src)
        self.codec = lossy_codec(src, self._cap)
        if self.codec is not None:
            self.reject_frozen = False
            if reject_frozen:
                lossy_warning(self.name, self.codec)

    def mark_bad(self, index: int, reason: str) -> None:
        """Record a bad frame (also used by later stages that reject a frame's content)."""
        log.warning("%s: frame %d rejected: %s", self.name, index, reason)
        self.bad.append((index, reason))

    def __iter__(self) -> Iterator[tuple[int, np.ndarray]]:
        raw = self._iter_sequence() if self._files is not None else self._iter_capture()
        seen_good, previous = False, None
        for index, frame in raw:
            self.n_frames = index + 1
            if frame is None:
                self.mark_bad(index, "cannot be decoded")
                continue
            gray = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
            shape = (gray.shape[1], gray.shape[0])
            if self.size is None:
                self.size = shape
            elif shape != tuple(self.size):
                if not seen_good:
                    raise DataFileError(self.name, f"frames are {shape[0]}×{shape[1]} px, the layout "
                                        f"needs {self.size[0]}×{self.size[1]} px")
                self.mark_bad(index, f"size {shape[0]}×{shape[1]} px instead of {self.size[0]}×{self.size[1]}")
                continue
            seen_good, previous, frozen = True, gray, _frozen_tile(gray, previous)
            if self.reject_frozen and frozen is not None:
                self.mark_bad(index, f"tile at column {frozen[0]}, row {frozen[1]} is identical to the "
                              "previous frame (decoder concealment or a stuck camera)")
                continue
            yield index, gray

    def _iter_capture(self):
        cap = self._cap
        expected = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        index = 0
        try:
            while True:
                ok, frame = cap.read()
                if not ok:
                    break
                yield index, frame
                index += 1
        finally:
            cap.release()
        if not _is_device(self.src) and expected > index:
            for missing in range(index, expected):
                self.n_frames = missing + 1
                self.mark_bad(missing, f"missing: the video ends after {index} of {expected} frames "
                              "(truncated or corrupt)")

    def _iter_sequence(self):
        for index, path in enumerate(self._files):
            yield index, cv2.imread(str(path), cv2.IMREAD_UNCHANGED)


def _frozen_tile(frame: np.ndarray, previous: np.ndarray | None) -> tuple[int, int] | None:
    """(column, row) px of the first non-uniform 16×16 tile equal to ``previous``'s, or None."""
    if previous is None or previous.shape != frame.shape:
        return None
    h, w = (frame.shape[0] // _TILE_PX) * _TILE_PX, (frame.shape[1] // _TILE_PX) * _TILE_PX
    same = (frame[:h, :w] == previous[:h, :w]).reshape(h // _TILE_PX, _TILE_PX, w // _TILE_PX, _TILE_PX)
    for r, c in zip(*np.nonzero(same.all(axis=(1, 3)))):
        tile = frame[r * _TILE_PX: (r + 1) * _TILE_PX, c * _TILE_PX: (c + 1) * _TILE_PX]
        if tile.min() != tile.max():
            return int(c * _TILE_PX), int(r * _TILE_PX)
    return None


def _sequence_files(pattern: str) -> list[Path]:
    """Files of a printf pattern from its first existing index (0 or 1) up to the first gap."""
    files = []
    start = 0 if Path(pattern % 0).exists() else 1
    i = start
    while Path(pattern % i).exists():
        files.append(Path(pattern % i))
        i += 1
    return files


def write_video(frames: np.ndarray, path: str | Path, fps: float = 30.0) -> Path:
    """Write grey frames (n, h, w) uint8 losslessly: FFV1 in ``.avi``/``.mkv``, or PNG
    files when ``path`` is a printf pattern (``frames/%05d.png``). Returns ``path``.

    Raises:
        ArgumentError: frames not (n, h, w) uint8, or an unsupported file suffix.
        DataFileError: the writer cannot be opened or a file cannot be written.
    """
    frames = np.asarray(frames)
    if frames.ndim != 3 or frames.dtype != np.uint8 or len(frames) == 0:
        raise ArgumentError("frames", f"{frames.dtype} array of shape {frames.shape}",
                            "a non-empty uint8 array (n, height, width)")
    text = str(path)
    if _PATTERN.search(text):
        Path(text % 0).parent.mkdir(parents=True, exist_ok=True)
        for i, frame in enumerate(frames):
            try:
                written = cv2.imwrite(text % i, frame)
            except cv2.error as exc:
                raise DataFileError(text % i, f"cannot write image: {str(exc).strip().splitlines()[-1]}") from None
            if not written:
                raise DataFileError(text % i, "cannot write image")
        return Path(path)
    if Path(text).suffix.lower() not in (".avi", ".mkv"):
        raise ArgumentError("path", text, "a .avi or .mkv file (lossless FFV1) or a %05d.png pattern")
    height, width = frames.shape[1:]
    writer = cv2.VideoWriter(text, cv2.VideoWriter_fourcc(*"FFV1"), float(fps), (width, height),
                             isColor=False)
    if not writer.isOpened():
        raise DataFileError(text, "cannot open a video writer (FFV1)")
    try:
        for frame in frames:
            writer.write(frame)
    finally:
        writer.release()
    return Path(path)
