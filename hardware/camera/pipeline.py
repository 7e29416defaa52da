"""One camera frame → the scanning element's displacement: the reading chain of ``feeler acquire``.

frame (grey uint8, the layout's size) → contact areas of every element's four feelers
(:class:`.extract.AreaExtractor`) → the scanning element's four areas → force by the area
law (:func:`feeler.models.optics.force_from_areas`) → displacement U = C F
(:func:`feeler.models.optics.displacement_from_force`). The campaign runner reads every
sample through it and the live decoder decodes frames through it
(:meth:`feeler.calib.neuron.LiveDecoder.push_frame`), so a frame decoded live gives the
displacement ``samples.csv`` records for it — one code path, not two.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.errors import ArgumentError
from feeler.models.optics import Layout, OpticsParams, displacement_from_force, force_from_areas

__all__ = ["FramePipeline", "FrameRejected", "Reading"]


class FrameRejected(ArgumentError):
    """A frame of the right size the area extractor refused (``problem``: why): the
    campaign takes the sample again from the next frame; a live caller may do the same."""

    def __init__(self, problem: str):
        self.problem = problem
        super().__init__("frame", f"rejected: {problem}", "a frame whose feeler discs can be measured")


@dataclass(frozen=True)
class Reading:
    """One sample's reading: ``areas_px2`` (4,) of the scanning element, ``force_n`` (3,)
    in N (x, y, z) and ``u_mm`` (3,) the displacement U = C F in mm (x, y, z)."""
    areas_px2: np.ndarray
    force_n: np.ndarray
    u_mm: np.ndarray


class FramePipeline:
    """The frame → displacement chain of one set-up.

    Args:
        layout (Layout): the camera's view (frame size, elements, feeler centres).
        element (int): index of the scanning element in ``layout.elements``.
        c_mm_per_n (ndarray[3, 3]): C of U = C F, mm/N.
        optics (OpticsParams): the area law (rest area, gains).
        blur_sd_px (float): the optics' blur (px), > 0.

    Calling it on a frame returns ``(areas (n_elements, 4) px², problem)`` like the
    extractor (the campaign retries a rejected frame); :meth:`reading` turns those areas
    into the scanning element's force and displacement; :meth:`read` does both, raising
    on a bad frame.
    """

    def __init__(self, layout: Layout, element: int, c_mm_per_n, optics: OpticsParams = OpticsParams(), *,
                 blur_sd_px: float = 1.2):
        from .extract import AreaExtractor

        n = len(layout.elements)
        if not (isinstance(element, (int, np.integer)) and 0 <= element < n):
            raise ArgumentError("element", element, f"an element index in 0..{n - 1} of layout {layout.name!r}")
        c = np.asarray(c_mm_per_n, float)
        if c.shape != (3, 3) or not np.all(np.isfinite(c)):
            raise ArgumentError("c_mm_per_n", c_mm_per_n, "a finite (3, 3) matrix in mm/N")
        self.layout, self.element, self.c_mm_per_n, self.optics = layout, int(element), c, optics
        self.shape = (layout.height_px, layout.width_px)
        self._extract = AreaExtractor(layout, blur_sd_px=blur_sd_px)

    @classmethod
    def of_plan(cls, plan_path: str | Path, calibration: str | Path | None = None) -> "FramePipeline":
        """The chain ``feeler acquire --plan PLAN [--calibration DIR]`` reads samples with
        (a run directory's ``scene.toml`` is its plan)."""
        from feeler.hardware.acquire.session import c_from_calibration, load_plan
        from feeler.hardware.acquire.world import optics_of_plan, plan_layout

        plan = load_plan(plan_path)
        return cls(plan_layout(plan, plan_path), plan.optics.element, c_from_calibration(calibration)[0],
                   optics_of_plan(plan), blur_sd_px=plan.optics.blur_sd_px)

    def check(self, frame) -> np.ndarray:
        """``frame`` as it is, if it is a grey uint8 array of the layout's size.

        Raises:
            ArgumentError: another type, dtype or shape (one line: what it is, what is allowed).
        """
        h, w = self.shape
        if not (isinstance(frame, np.ndarray) and frame.dtype == np.uint8 and frame.shape == self.shape):
            what = (f"{frame.dtype} array of shape {frame.shape}" if isinstance(frame, np.ndarray)
                    else type(frame).__name__)
            raise ArgumentError("frame", what, f"a grey uint8 frame of {w}×{h} px (shape ({h}, {w}), "
                                f"layout {self.layout.name!r})")
        return frame

    def __call__(self, frame: np.ndarray) -> tuple[np.ndarray, str | None]:
        """Areas (n_elements, 4) px² of a frame, or NaN areas and why it was rejected."""
        return self._extract(frame)

    def reading(self, areas_px2) -> Reading:
        """The scanning element's reading from the areas of every element (n_elements, 4)
        or of the scanning element alone (4,), px².

        Raises:
            ArgumentError: another shape, or non-finite areas.
        """
        a = np.asarray(areas_px2, float)
        n = len(self.layout.elements)
        if a.shape == (n, 4):
            a = a[self.element]
        elif a.shape != (4,):
            raise ArgumentError("areas", f"array of shape {a.shape}",
                                f"the scanning element's 4 areas or all elements' ({n}, 4), px²")
        if not np.all(np.isfinite(a)):
            raise ArgumentError("areas", a.tolist(), "finite areas in px²")
        f = force_from_areas(a, self.optics)
        return Reading(a, f, displacement_from_force(f, self.c_mm_per_n))

    def read(self, frame) -> Reading:
        """:meth:`check`, extract, :meth:`reading`.

        Raises:
            ArgumentError: a frame of another type, dtype or shape.
            FrameRejected: a frame the extractor refused (why, in one line).
        """
        areas, problem = self(self.check(frame))
        if problem is not None:
            raise FrameRejected(problem)
        return self.reading(areas)
