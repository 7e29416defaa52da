"""The `images` fidelity of the optical sensor: displacement seen through rendered frames.

U → F = C⁻¹ U → contact areas (area law) → camera frames of the element array (blur, shot
noise, 8 bits) → optionally a lossless video file → the OpenCV reading chain of
:mod:`feeler.hardware.camera` → areas → F̂ → Û = C F̂.

The series of ``u_mm`` (all leading axes flattened) are packed onto the array's elements:
frame ``g · n_time + t`` shows, at time step ``t``, series ``g · n_elements + e`` on element
``e``; elements without a series of their own rest at zero force. A frame the reader
rejects turns every series it carries into NaN at that time step (never used; a line per
frame at INFO, shown with ``-v``), or with ``strict`` raises :class:`FramesRejected`, which
sums the reasons up (:func:`rejection_cause`: shot noise, discs too small or too large).
OpenCV is imported only when frames are read (inside :func:`observe_images`), so importing
this module and registering the fidelities stays light.
"""
from __future__ import annotations

import logging
from collections import Counter
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.calib.progress import progress as bar
from feeler.calib.progress import stage
from feeler.errors import ArgumentError, FeelerError
from feeler.models.optics import (CameraParams, Layout, OpticsParams, areas_from_force,
                                  displacement_from_force, force_from_areas,
                                  force_from_displacement, render_frames)

__all__ = ["observe_images", "frames_from_displacement", "ImagesFidelity", "register_optical_fidelities",
           "FramesRejected", "rejection_cause"]

_CHUNK_FRAMES = 32  # frames rendered per call (bounds the disc patches to ~40 MB)

log = logging.getLogger(__name__)

# the reader's reasons (feeler.hardware.camera.extract) by what is at fault
_CAUSES = (("noise", ("saturated pixels", "a bright blob outside", "blobs in the window")),
           ("small discs", ("no disc interior", "no disc found")),
           ("large discs", ("reaches the edge of its feeler window",)))


class FramesRejected(FeelerError):
    """Rendered frames the reader refused (:func:`observe_images` with ``strict``).

    Attributes:
        problems (tuple[tuple[int, str], ...]): (frame, reason) of every rejected frame.
        n_frames (int): frames rendered.
        series (ndarray[k] of int): the series (leading axes of ``u_mm`` flattened) that
            lost a time step, increasing.
        cause (str): :func:`rejection_cause` of the reasons.
    """

    def __init__(self, problems, n_frames: int, series: np.ndarray):
        self.problems, self.n_frames, self.series = tuple(problems), int(n_frames), np.asarray(series, int)
        self.cause = rejection_cause(reason for _, reason in self.problems)
        first, reason = self.problems[0]
        super().__init__(f"the frame reader rejected {len(self.problems)} of {self.n_frames} rendered frames "
                         f"({self.cause}; first: frame {first}, {reason})")


def rejection_cause(reasons) -> str:
    """What the reader's reasons for rejecting frames point to, by majority: ``"noise"``
    (saturated pixels, stray or split blobs: shot noise), ``"small discs"`` (no disc
    interior to measure the peak level, a disc lost as a speck: discs small for the blur),
    ``"large discs"`` (a disc reaching its window's edge) or ``"other"`` (decoding, frozen
    or missing video frames)."""
    votes = Counter(next((cause for cause, marks in _CAUSES if any(m in reason for m in marks)), "other")
                    for reason in reasons)
    return votes.most_common(1)[0][0] if votes else "other"


class _AtInfo(logging.Filter):
    """The camera reader's per-frame warnings as INFO lines (shown with ``-v``)."""

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno != logging.WARNING:
            return True
        record.levelno, record.levelname = logging.INFO, "INFO"
        return logging.getLogger(record.name).isEnabledFor(logging.INFO)


@contextmanager
def _reader_lines_at_info(*names: str):
    loggers, quiet = [logging.getLogger(n) for n in names], _AtInfo()
    for logger in loggers:
        logger.addFilter(quiet)
    try:
        yield
    finally:
        for logger in loggers:
            logger.removeFilter(quiet)


def frames_from_displacement(u_mm: np.ndarray, *, params: OpticsParams, layout: Layout,
                             rng: np.random.Generator, camera: CameraParams | None = None,
                             progress: bool | None = False) -> np.ndarray:
    """Camera frames (n_groups · n_time, H, W) uint8 showing the series of ``u_mm``
    (..., n_time, 3) packed onto the layout's elements as described in the module.
    ``progress``: None or True, a line on stderr and a bar over the frames on a terminal
    (True: everywhere); False, silent."""
    camera = CameraParams() if camera is None else camera
    series = _series(u_mm)
    n_series, n_time, _ = series.shape
    n_el = len(layout.elements)
    n_groups = -(-n_series // n_el)
    u = np.zeros((n_groups * n_el, n_time, 3))
    u[:n_series] = series
    areas = areas_from_force(force_from_displacement(u, params.c_matrix), params)
    per_frame = areas.reshape(n_groups, n_el, n_time, 4).transpose(0, 2, 1, 3).reshape(-1, n_el, 4)
    stage(f"rendering {len(per_frame)} camera frames of {n_el} elements", progress)
    chunks = range(0, len(per_frame), _CHUNK_FRAMES)
    return np.concatenate([render_frames(per_frame[i: i + _CHUNK_FRAMES], layout, camera, rng)
                           for i in bar(chunks, desc=f"rendering batches of {_CHUNK_FRAMES} frames", enabled=progress)])


def observe_images(u_mm: np.ndarray, *, params: OpticsParams, layout: Layout,
                   rng: np.random.Generator, video_path: str | Path | None = None,
                   camera: CameraParams | None = None, progress: bool | None = False,
                   strict: bool = False) -> np.ndarray:
    """Measured tip displacement at the `images` fidelity.

    Args:
        u_mm (ndarray[..., n_time, 3]): true tip displacement (mm), order (x, y, z).
        params (OpticsParams): the element (C, area law); C also reads U back.
        layout (Layout): the camera's view of the element array.
        rng (numpy.random.Generator): the shot-noise source.
        video_path (path | None): when given, the frames are written there losslessly
            (``.avi``/``.mkv`` FFV1 or a ``%05d.png`` pattern) and read back with
            ``cv2.VideoCapture``/``cv2.imread``; otherwise they are read in memory.
        camera (CameraParams | None): levels, blur and shot noise; default ``CameraParams()``.
        progress (bool | None): None, a line per stage (render, write, read) on stderr and
            bars over the frames on a terminal; True, bars everywhere; False, silent.
        strict (bool): raise when a frame is rejected instead of returning NaN.

    Returns:
        ndarray[..., n_time, 3]: measured displacement (mm), NaN where a frame was bad.

    Raises:
        FramesRejected: ``strict`` and the reader rejected a frame (every reason in it;
            each is also logged at INFO).
    """
    from feeler.hardware.camera import AreaExtractor, read_source, write_video
    from feeler.hardware.camera.source import FrameReader

    camera = CameraParams() if camera is None else camera
    u = np.asarray(u_mm, dtype=float)
    frames = frames_from_displacement(u, params=params, layout=layout, rng=rng, camera=camera, progress=progress)
    n_el = len(layout.elements)
    areas = np.full((len(frames), n_el, 4), np.nan)
    if video_path is not None:
        stage(f"writing {len(frames)} frames to {video_path} and reading them back", progress)
        write_video(frames, video_path)
        with _reader_lines_at_info(read_source.__module__, FrameReader.__module__):
            reading = read_source(video_path, layout, params, blur_sd_px=camera.blur_sd_px,
                                  reject_frozen=bool(np.isfinite(camera.photons_per_level)))
        areas[reading.index] = reading.areas_px2
        problems = list(reading.bad)
    else:
        extract = AreaExtractor(layout, blur_sd_px=camera.blur_sd_px)
        stage(f"reading the contact areas off {len(frames)} frames (OpenCV)", progress)
        problems = []
        for i, frame in enumerate(bar(frames, desc="reading frames", enabled=progress)):
            found, problem = extract(frame)
            if problem is None:
                areas[i] = found
            else:
                log.info("rendered frame %d rejected: %s", i, problem)
                problems.append((i, problem))
    n_series, n_time = int(np.prod(u.shape[:-2], dtype=int)), u.shape[-2]
    per_series = areas.reshape(-1, n_time, n_el, 4).transpose(0, 2, 1, 3).reshape(-1, n_time, 4)
    measured = displacement_from_force(force_from_areas(per_series[:n_series], params), params.c_matrix)
    if strict and problems:
        raise FramesRejected(problems, len(frames), np.flatnonzero(np.isnan(measured).any(axis=(1, 2))))
    return measured.reshape(u.shape)


def _series(u_mm: np.ndarray) -> np.ndarray:
    u = np.asarray(u_mm, dtype=float)
    if u.ndim < 2 or u.shape[-1] != 3 or u.shape[-2] < 1:
        raise ArgumentError("u_mm", f"array of shape {u.shape}", "shape (..., n_time, 3)")
    if not np.all(np.isfinite(u)):
        raise ArgumentError("u_mm", "non-finite values", "finite displacements (mm)")
    return u.reshape(-1, *u.shape[-2:])


@dataclass(frozen=True)
class ImagesFidelity:
    """Everything the `images` fidelity needs, as one ``params`` object for
    :func:`feeler.models.sensor.observe` (``optics``, ``layout``, ``camera``, ``video_path``,
    ``progress`` and ``strict`` as in :func:`observe_images`)."""

    optics: OpticsParams
    layout: Layout
    camera: CameraParams = CameraParams()
    video_path: str | None = None
    progress: bool | None = False
    strict: bool = False


def register_optical_fidelities() -> None:
    """Plug `areas` (params: OpticsParams) and `images` (params: ImagesFidelity) into
    :data:`feeler.models.sensor.FIDELITIES`."""
    from feeler.models.optics import observe_areas
    from feeler.models.sensor import register_fidelity

    register_fidelity("areas", lambda u, p, rng: observe_areas(u, params=p, rng=rng))
    register_fidelity("images", lambda u, p, rng: observe_images(
        u, params=p.optics, layout=p.layout, rng=rng, video_path=p.video_path, camera=p.camera, progress=p.progress,
        strict=p.strict))
