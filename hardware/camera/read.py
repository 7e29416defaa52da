"""The camera reading chain: source → frames → feeler areas → force → displacement."""
from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.errors import ArgumentError
from feeler.models.optics import Layout, OpticsParams, displacement_from_force, force_from_areas

from .extract import AreaExtractor
from .source import FrameReader

__all__ = ["CameraReading", "read_source"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class CameraReading:
    """What a source yielded, good frames only (bad ones are listed, never used).

    Attributes:
        index (ndarray[n]): frame number of each good frame in the source.
        areas_px2 (ndarray[n, n_elements, 4]): feeler contact areas (px²).
        force_n (ndarray[n, n_elements, 3]): element force (N), order (x, y, z).
        u_mm (ndarray[n, n_elements, 3]): tip displacement U = C F (mm).
        n_frames (int): frames attempted in the source, good and bad.
        bad (tuple[tuple[int, str], ...]): (frame number, reason) of every bad frame.
    """

    index: np.ndarray
    areas_px2: np.ndarray
    force_n: np.ndarray
    u_mm: np.ndarray
    n_frames: int
    bad: tuple[tuple[int, str], ...]


def read_source(src: int | str | Path, layout: Layout, params: OpticsParams, *,
                c_mm_per_n: np.ndarray | None = None, blur_sd_px: float = 1.2,
                levels: tuple[float, float] | None = None,
                max_frames: int | None = None, reject_frozen: bool = True) -> CameraReading:
    """Read a camera source through to displacement.

    Args:
        src: camera index, video file or image-sequence pattern (``frames/%05d.png``).
        layout (Layout): regions and feeler centres; frames must match its size.
        params (OpticsParams): the area law (rest area and gains).
        c_mm_per_n (ndarray[3, 3] | None): force→displacement matrix used to read U
            (e.g. the posterior mean of the M1 calibration); default ``params``' C.
        blur_sd_px (float): the optics' blur (px), sets the extraction's reach.
        levels ((background, peak) | None): known grey levels, or estimated per frame.
        max_frames (int | None): stop after this many frames (for a live camera).
        reject_frozen (bool): reject frames with a tile frozen from the previous frame
            (see :class:`FrameReader`); ``False`` for noise-free synthetic video.

    Raises:
        DataFileError: the source cannot be opened, or its frames have the wrong size.
        ArgumentError: a C that is not a 3×3 finite matrix.
    """
    c = params.c_matrix if c_mm_per_n is None else np.asarray(c_mm_per_n, dtype=float)
    if c.shape != (3, 3) or not np.all(np.isfinite(c)):
        raise ArgumentError("c_mm_per_n", c_mm_per_n, "a finite 3×3 matrix (mm/N)")
    reader = FrameReader(src, size=(layout.width_px, layout.height_px), reject_frozen=reject_frozen)
    extract = AreaExtractor(layout, blur_sd_px=blur_sd_px, levels=levels)
    index, areas = [], []
    for i, frame in reader:
        found, problem = extract(frame)
        if problem is not None:
            reader.mark_bad(i, problem)
        else:
            index.append(i)
            areas.append(found)
        if max_frames is not None and reader.n_frames >= max_frames:
            break
    n_el = len(layout.elements)
    areas_arr = np.array(areas).reshape(-1, n_el, 4)
    force = force_from_areas(areas_arr, params)
    if reader.bad:
        log.warning("%s: %d of %d frames bad", reader.name, len(reader.bad), reader.n_frames)
    return CameraReading(index=np.array(index, dtype=int), areas_px2=areas_arr, force_n=force,
                         u_mm=displacement_from_force(force, c), n_frames=reader.n_frames,
                         bad=tuple(sorted(reader.bad)))
