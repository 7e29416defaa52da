"""Cameras of a campaign: a real source through ``cv2.VideoCapture``, or the virtual camera.

Both offer ``name``, ``start_scan(scan_id)``, ``grab(stage_mm, sample) -> Grab``, ``end_scan()``
and ``close()``. A grab
is a frame (grey uint8, the layout's size) or a reason why there is none; a bad frame is
returned with its reason (the campaign counts and logs it and grabs again), never used.

:class:`CaptureCamera` reads a device index, a video file or an image sequence (one frame
per grab); a file that runs out of frames is an error naming it (:class:`DataFileError`).
:class:`VirtualCamera` renders the optical sensor for the stage's position over the plan's
plate (:mod:`.world`) and records every frame it delivers into a lossless FFV1 video per
scan, ``video/scan_NNNN.avi``, which replays through :class:`CaptureCamera`. It renders the
sensor where the stage stood at the sample's recorded time (the position of its status
query), with shot noise drawn for that sample alone (``SeedSequence([seed, scan, sample,
try])``): two runs of one plan and seed draw the same noise for every sample, so they
differ only where the stage was when the sample was read — which the time base records.
"""
from __future__ import annotations

import logging
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.errors import DataFileError

__all__ = ["Grab", "CaptureCamera", "VirtualCamera", "video_path", "sample_rng"]

log = logging.getLogger("feeler.acquire")


@dataclass(frozen=True)
class Grab:
    """One frame: ``t_s`` (monotonic clock, s), ``frame`` (uint8[h, w] or None), ``problem``."""

    t_s: float
    frame: np.ndarray | None
    problem: str | None = None


def sample_rng(seed: int, scan_id: int, sample: int, tries: int = 0) -> np.random.Generator:
    """The virtual camera's noise for one try at one sample of one scan."""
    return np.random.default_rng(np.random.SeedSequence([seed, scan_id, sample, tries]))


def video_path(run_dir: Path, scan_id: int) -> Path:
    """Where the virtual camera records scan ``scan_id``."""
    return Path(run_dir) / "video" / f"scan_{scan_id:04d}.avi"


class CaptureCamera:
    """A device index, video file or ``%05d.png`` sequence, read one frame per grab.

    Raises (on open): DataFileError naming the source (no device, no file, undecodable, a
    file's frames not of ``size``).
    """

    def __init__(self, src: str, size: tuple[int, int]):
        from feeler.hardware.camera import open_source

        self.src, self.size = src, tuple(size)
        self.name = f"camera {src}" if str(src).isdigit() else str(src)
        self.is_device = str(src).isdigit()
        self._cap = open_source(int(src) if self.is_device else src)
        self._previous, self.n_read = None, 0
        from feeler.hardware.camera.source import lossy_codec, lossy_warning

        self.codec = lossy_codec(int(src) if self.is_device else src, self._cap)   # e.g. a webcam's MJPG stream
        if self.codec is not None:
            lossy_warning(self.name, self.codec)
        if not self.is_device:
            self._check_size()

    def _check_size(self) -> None:
        """A video file or image sequence whose frames are not the layout's size fails here,
        before the stage moves, instead of as bad frames once the campaign has started (a
        source whose container does not state its size is checked frame by frame)."""
        import cv2

        shape = (int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        if min(shape) > 0 and shape != self.size:
            self._cap.release()
            raise DataFileError(self.name, f"frames are {shape[0]}×{shape[1]} px; the plan's camera layout is "
                                f"{self.size[0]}×{self.size[1]} px (record at that size, or name this camera's "
                                "layout file in the plan's [optics] layout)")

    def check_frames(self, needed: int, what: str) -> None:
        """A video file or image sequence with fewer frames than ``needed`` fails here, before
        the stage moves: a recorded scan's video replayed under a plan of four scans ran its
        first scan, then stopped with 'the video ended (truncated or corrupt)' (an outside
        audit). The count it states is checked first, then the frames it really holds."""
        import cv2

        if self.is_device:
            return
        count = int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT))
        if 0 < count < needed:
            self._cap.release()
            raise DataFileError(self.name, f"holds {count} frames; {what} needs at least {needed}, one per sample "
                                "(a run's video/scan_NNNN.avi replays its one scan: use a plan of that scan, or "
                                "an image sequence of the whole run)")
        # a file cut short still states its whole count (an audit's half.avi: 41 stated, 20 decodable),
        # and the stage moved and 20 frames were taken, 11.9 s, before 'the video ended': the frames
        # are grabbed (not decoded into images) up to what the plan needs, then the source reopened
        readable = 0
        while readable < needed and self._cap.grab():
            readable += 1
        self._cap.release()
        if readable < needed:
            stated = f", though it states {count}" if count > readable else ""
            raise DataFileError(self.name, f"holds {readable} readable frames{stated}; {what} needs at least "
                                f"{needed}, one per sample (the file is cut short or corrupt)")
        from feeler.hardware.camera import open_source

        self._cap = open_source(self.src)

    def start_scan(self, scan_id: int) -> None:
        pass

    def end_scan(self) -> None:
        pass

    def grab(self, stage_mm, sample: int | None = None) -> Grab:
        import cv2

        from feeler.hardware.camera.source import _frozen_tile

        ok, frame = self._cap.read()
        now = time.monotonic()
        if not ok:
            if self.is_device:
                return Grab(now, None, "the camera delivered no frame")
            raise DataFileError(self.name, f"no frame after {self.n_read} frames: the video ended "
                                "(truncated or corrupt) before the plan did")
        self.n_read += 1
        gray = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        shape = (gray.shape[1], gray.shape[0])
        if shape != self.size:
            return Grab(now, None, f"size {shape[0]}×{shape[1]} px instead of {self.size[0]}×{self.size[1]} px")
        frozen, self._previous = _frozen_tile(gray, self._previous), gray
        if frozen is not None and self.codec is None:
            return Grab(now, None, f"tile at column {frozen[0]}, row {frozen[1]} identical to the previous "
                        "frame (decoder concealment or a stuck camera)")
        return Grab(now, gray)

    def close(self) -> None:
        self._cap.release()


class VirtualCamera:
    """Renders the scanning element for the stage position; records each scan's video.

    Args:
        world (VirtualWorld): plate, tip and optics of the emulated set-up.
        run_dir (Path): the run directory (videos go to ``video/``).
        seed (int): root of the shot noise: try ``j`` at sample ``k`` of scan ``i`` draws from
            ``SeedSequence([seed, i, k, j])`` (:func:`sample_rng`).
    """

    def __init__(self, world, run_dir: Path, seed: int):
        self.world, self.run_dir, self.seed = world, Path(run_dir), seed
        self.name = "virtual camera"
        self._writer, self._scan, self._tries = None, None, {}

    def start_scan(self, scan_id: int) -> None:
        import cv2

        self.end_scan()
        path = video_path(self.run_dir, scan_id)
        path.parent.mkdir(parents=True, exist_ok=True)
        layout = self.world.layout
        self._writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), 10.0,
                                       (layout.width_px, layout.height_px), isColor=False)
        if not self._writer.isOpened():
            raise DataFileError(path, "cannot open a video writer (FFV1)")
        self._scan, self._tries = scan_id, {}

    def grab(self, stage_mm, sample: int = 0) -> Grab:
        tries = self._tries[sample] = self._tries.get(sample, -1) + 1
        frame = self.world.render(self._scan, stage_mm, sample_rng(self.seed, self._scan, sample, tries))
        self._writer.write(frame)
        return Grab(time.monotonic(), frame)

    def end_scan(self) -> None:
        """Finish the scan's video file."""
        if self._writer is not None:
            self._writer.release()
            self._writer = None

    close = end_scan
