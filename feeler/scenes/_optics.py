"""The ``[optics]`` table shared by scene kinds whose sensor can run at the optical fidelities.

With ``sensor.fidelity = "areas"`` or ``"images"`` the measured displacement (or force)
goes through the optical element (:mod:`feeler.models.optics`): its area law, and at
``images`` rendered camera frames read back by OpenCV. The table is optional (defaults
below) and refused at the ``displacement`` fidelity, where it would be silently unused.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.errors import SceneError
from feeler.scene import param

__all__ = ["Optics", "check_optics", "optics_params", "fidelity_params", "OPTICAL"]

OPTICAL = ("areas", "images")
_NOMINAL_C = ((1.0, 0.0, 0.02), (0.05, 0.5, 0.05), (0.02, 0.0, 1.0))


@dataclass(frozen=True, kw_only=True)
class Optics:
    layout: str = param("", doc="camera layout TOML, relative to the scene file; empty: a 4x4 grid, 640x480 px")
    c_mm_per_n: tuple[tuple[float, ...], ...] = param(_NOMINAL_C, lo=-10.0, hi=10.0, min_len=3,
                                                      doc="3x3 force->displacement matrix of the element, mm/N")
    # the optics' nominal 150 px²: the frame reader measures discs down to ~95 px² at blur 1.2 px
    rest_area_px2: float = param(150.0, lo=0.0, lo_open=True, hi=1e4, doc="px², feeler area at zero force")
    gain_y_px2_per_n: float = param(800.0, lo=0.0, lo_open=True, hi=1e6, doc="px²/N, summed area per N of F_y")
    gain_x_px2_per_n: float = param(400.0, lo=0.0, lo_open=True, hi=1e6, doc="px²/N, area difference per N of F_x")
    gain_z_px2_per_n: float = param(400.0, lo=0.0, lo_open=True, hi=1e6, doc="px²/N, area difference per N of F_z")
    area_sd_px2: float = param(0.25, lo=0.0, hi=1e3, doc="px², area noise (areas fidelity)")
    area_step_px2: float = param(1.0, lo=0.0, hi=1e3, doc="px², area quantisation step (areas fidelity; 0 none)")
    blur_sd_px: float = param(1.2, lo=0.0, hi=10.0, doc="px, optical blur (images fidelity)")
    photons_per_level: float = param(40.0, lo=0.0, lo_open=True, hi=1e9,
                                     doc="photons per grey level, shot noise (images fidelity)")
    video: bool = param(False, doc="images: write the frames to DIR/sensor.avi (FFV1) and read them back "
                                   "through cv2.VideoCapture")


def check_optics(optics: Optics | None, fidelity: str, path) -> None:
    """Refuse ``[optics]`` at the displacement fidelity, and a C that is not 3×3 invertible."""
    if optics is None:
        return
    if fidelity not in OPTICAL:
        raise SceneError(path, "optics", f"only used when sensor.fidelity is {' or '.join(OPTICAL)} "
                         f"(it is {fidelity!r}); remove the table")
    c = optics.c_mm_per_n
    if len(c) != 3 or any(len(row) != 3 for row in c):
        raise SceneError(path, "optics.c_mm_per_n", "must be 3 rows of 3 numbers (mm/N)")
    if np.linalg.cond(np.asarray(c, dtype=float)) > 1e8:
        raise SceneError(path, "optics.c_mm_per_n", "must be invertible (condition number <= 1e8)")


def optics_params(optics: Optics | None, c_mm_per_n=None):
    """The :class:`OpticsParams` of the table (``c_mm_per_n`` overrides its C)."""
    from feeler.models.optics import OpticsParams

    o = optics or Optics()
    return OpticsParams(c_mm_per_n=o.c_mm_per_n if c_mm_per_n is None else c_mm_per_n,
                        rest_area_px2=o.rest_area_px2, gain_y_px2_per_n=o.gain_y_px2_per_n,
                        gain_x_px2_per_n=o.gain_x_px2_per_n, gain_z_px2_per_n=o.gain_z_px2_per_n,
                        area_sd_px2=o.area_sd_px2, area_step_px2=o.area_step_px2)


def fidelity_params(optics: Optics | None, fidelity: str, *, scene_path, out_dir=None, c_mm_per_n=None,
                    progress: bool | None = False):
    """``params`` for :func:`feeler.models.sensor.observe` at an optical fidelity (and
    registers those fidelities). ``out_dir`` receives ``sensor.avi`` when ``video``;
    ``progress`` is the `images` fidelity's (stage lines and frame bars, False: silent);
    at `images` rejected frames raise :class:`~feeler.simulate.images.FramesRejected`
    (``strict``), which :func:`rejection_error` turns into the scene's one-line error."""
    from feeler.models.optics import CameraParams
    from feeler.scenes._frames import scene_layout
    from feeler.simulate.images import ImagesFidelity, register_optical_fidelities

    register_optical_fidelities()
    o = optics or Optics()
    params = optics_params(o, c_mm_per_n)
    if fidelity == "areas":
        return params
    video = str(Path(out_dir) / "sensor.avi") if o.video and out_dir is not None else None
    return ImagesFidelity(params, scene_layout(o, scene_path),
                          CameraParams(blur_sd_px=o.blur_sd_px, photons_per_level=o.photons_per_level),
                          video, progress, strict=True)
