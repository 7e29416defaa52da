"""The emulated set-up behind ``feeler acquire --emulate``: plates, tip and optical sensor.

For a stage position (x, y, z) over scan ``i``'s plate the tip's true displacement is

    depth = surface_z − z            (press into the plate, mm; no contact when ≤ 0)
    U_y = depth + h̄(x − origin_x)    (h̄: the plate's step height under the pressed face,
                                      :func:`feeler.models.probe.smoothed_height_mm`)
    U_x = −shear_per_normal · U_y,  U_z = 0

and a frame shows the scanning element's four contact areas for F = C⁻¹ U (nominal
optics with the plan's rest area) while every other element rests at zero force (:func:`feeler.models.optics.render_frames`).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from feeler.errors import SceneError
from feeler.models import probe, surface
from feeler.models.optics import (CameraParams, Layout, OpticsParams, areas_from_force,
                                  force_from_displacement, grid_layout, load_layout, render_frames)

from .plan import scans_of

__all__ = ["VirtualWorld", "plan_layout", "layout_file", "RUN_LAYOUT", "optics_of_plan", "tip_displacement_mm"]


RUN_LAYOUT = "layout.toml"      # a run directory's copy of its plan's layout file (:mod:`.store`)


def layout_file(plan, plan_path: str | Path) -> Path | None:
    """The plan's layout file: ``optics.layout`` relative to the plan's directory; for a run
    directory's copy of its plan (``RUN/scene.toml``, which ``--resume`` is told to pass),
    the run's copy of the layout when the relative path does not reach the original. None:
    the plan names no layout (the default grid)."""
    name = plan.optics.layout
    if not name:
        return None
    here = Path(plan_path).parent
    path = here / name
    if not path.is_file() and Path(plan_path).name == "scene.toml" and (here / "journal.jsonl").is_file() \
            and (here / RUN_LAYOUT).is_file():
        return here / RUN_LAYOUT
    return path


def plan_layout(plan, plan_path: str | Path) -> Layout:
    """The plan's camera layout (:func:`layout_file`, or the default 4×4 grid), checked to
    hold the scanning element ``optics.element``."""
    name = plan.optics.layout
    path = layout_file(plan, plan_path)
    if path is not None and not path.is_file():      # name the plan and its key, not only the path it made
        raise SceneError(plan_path, "optics.layout", f"{name!r}: no such layout file ({path}; a path relative to "
                                                     f"the plan's directory)")
    layout = load_layout(path) if path is not None else grid_layout()
    if plan.optics.element >= len(layout.elements):
        raise SceneError(plan_path, "optics.element", f"{plan.optics.element}: the layout "
                         f"{layout.name!r} has {len(layout.elements)} elements")
    return layout


def optics_of_plan(plan) -> OpticsParams:
    """The area law of the plan's sensor (nominal optics with the plan's rest area)."""
    return OpticsParams(rest_area_px2=plan.optics.rest_area_px2)


def tip_displacement_mm(virtual, surface_z_mm: float, origin_x_mm: float, step_mm: float,
                        stage_mm) -> np.ndarray:
    """True tip displacement (3,) mm for a stage position (x, y, z) mm over one plate."""
    x, _, z = (float(v) for v in stage_mm)
    depth = surface_z_mm - z
    if depth <= 0:
        return np.zeros(3)
    profile = surface.step(virtual.step_position_mm, step_mm)
    face = probe.Footprint(virtual.pad_width_mm, depth)
    uy = depth + float(probe.smoothed_height_mm(profile, x - origin_x_mm, face))
    uy = max(uy, 0.0)
    return np.array([-virtual.shear_per_normal * uy, uy, 0.0])


@dataclass(frozen=True)
class VirtualWorld:
    """Plan + layout + optics of the emulated campaign (see the module docstring)."""

    plan: object
    layout: Layout
    optics: OpticsParams = OpticsParams()
    camera: CameraParams = CameraParams()

    @classmethod
    def of_plan(cls, plan, plan_path: str | Path) -> "VirtualWorld":
        if plan.virtual is None:
            raise SceneError(plan_path, "virtual", "missing [virtual] table (step_position_mm, ...) "
                             "needed by --emulate")
        return cls(plan, plan_layout(plan, plan_path), optics_of_plan(plan),
                   CameraParams(blur_sd_px=plan.optics.blur_sd_px))

    def truth_mm(self, scan_id: int, stage_mm) -> np.ndarray:
        """True U (3,) mm of scan ``scan_id`` at a stage position."""
        spec = scans_of(self.plan)[scan_id]
        return tip_displacement_mm(self.plan.virtual, self.plan.plates.surface_z_mm, spec.origin_x_mm,
                                   spec.step_mm, stage_mm)

    def render(self, scan_id: int, stage_mm, rng: np.random.Generator) -> np.ndarray:
        """One frame (h, w) uint8 of the element array for a stage position."""
        u = np.zeros((len(self.layout.elements), 3))
        u[self.plan.optics.element] = self.truth_mm(scan_id, stage_mm)
        areas = areas_from_force(force_from_displacement(u, self.optics.c_matrix), self.optics)
        return render_frames(areas[None], self.layout, self.camera, rng)[0]
