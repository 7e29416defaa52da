"""The `images` fidelity of the optical sensor: displacement seen through rendered frames.

U → F = C⁻¹ U → contact areas (area law) → camera frames of the element array (blur, shot
noise, 8 bits) → optionally a lossless video file → the OpenCV reading chain of
:mod:`feeler.hardware.camera` → areas → F̂ → Û = C F̂.

The series of ``u_mm`` (all leading axes flattened) are packed onto the array's elements:
frame ``g · n_time + t`` shows, at time step ``t``, series ``g · n_elements + e`` on element
``e``; elements without a series of their own rest at zero force. A frame the reader
rejects turns every series it carries into NaN at that time step (logged, never used).
OpenCV is imported only when frames are read (inside :func:`observe_images`), so importing
this module and registering the fidelities stays light.
"""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.calib.progress import progress as bar
from feeler.calib.progress import stage
from feeler.errors import ArgumentError
from feeler.models.optics import (CameraParams, Layout, OpticsParams, areas_from_force,
                                  displacement_from_force, force_from_areas,
                                  force_from_displacement, render_frames)

__all__ = ["observe_images", "frames_from_displacement", "ImagesFidelity", "register_optical_fidelities"]

_CHUNK_FRAMES = 32  # frames rendered per call (bounds the disc patches to ~40 MB)

log = logging.getLogger(__name__)


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
                   camera: CameraParams | None = None, progress: bool | None = False) -> np.ndarray:
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

    Returns:
        ndarray[..., n_time, 3]: measured displacement (mm), NaN where a frame was bad.
    """
    from feeler.hardware.camera import AreaExtractor, read_source, write_video

    camera = CameraParams() if camera is None else camera
    u = np.asarray(u_mm, dtype=float)
    frames = frames_from_displacement(u, params=params, layout=layout, rng=rng, camera=camera, progress=progress)
    n_el = len(layout.elements)
    areas = np.full((len(frames), n_el, 4), np.nan)
    if video_path is not None:
        stage(f"writing {len(frames)} frames to {video_path} and reading them back", progress)
        write_video(frames, video_path)
        reading = read_source(video_path, layout, params, blur_sd_px=camera.blur_sd_px,
                              reject_frozen=bool(np.isfinite(camera.photons_per_level)))
        areas[reading.index] = reading.areas_px2
    else:
        extract = AreaExtractor(layout, blur_sd_px=camera.blur_sd_px)
        stage(f"reading the contact areas off {len(frames)} frames (OpenCV)", progress)
        for i, frame in enumerate(bar(frames, desc="reading frames", enabled=progress)):
            found, problem = extract(frame)
            if problem is None:
                areas[i] = found
            else:
                log.warning("rendered frame %d rejected: %s", i, problem)
    n_series, n_time = int(np.prod(u.shape[:-2], dtype=int)), u.shape[-2]
    per_series = areas.reshape(-1, n_time, n_el, 4).transpose(0, 2, 1, 3).reshape(-1, n_time, 4)
    measured = displacement_from_force(force_from_areas(per_series[:n_series], params), params.c_matrix)
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
    and ``progress`` as in :func:`observe_images`)."""

    optics: OpticsParams
    layout: Layout
    camera: CameraParams = CameraParams()
    video_path: str | None = None
    progress: bool | None = False


def register_optical_fidelities() -> None:
    """Plug `areas` (params: OpticsParams) and `images` (params: ImagesFidelity) into
    :data:`feeler.models.sensor.FIDELITIES`."""
    from feeler.models.optics import observe_areas
    from feeler.models.sensor import register_fidelity

    register_fidelity("areas", lambda u, p, rng: observe_areas(u, params=p, rng=rng))
    register_fidelity("images", lambda u, p, rng: observe_images(
        u, params=p.optics, layout=p.layout, rng=rng, video_path=p.video_path, camera=p.camera, progress=p.progress))
