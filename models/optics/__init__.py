"""The optical three-axis tactile sensor: area law, camera layout, rendered frames.

numpy/scipy only; the reading side (OpenCV) lives in :mod:`feeler.hardware.camera`.
"""
from .law import (OpticsParams, areas_from_force, displacement_from_force, force_from_areas,
                  force_from_displacement)
from .layout import Element, Layout, grid_layout, layout_toml, load_layout
from .observe import measure_areas, observe_areas
from .render import CameraParams, blur_margin_px, render_frames

__all__ = [
    "OpticsParams", "areas_from_force", "force_from_areas", "force_from_displacement",
    "displacement_from_force", "Element", "Layout", "grid_layout", "load_layout", "layout_toml",
    "observe_areas", "measure_areas", "CameraParams", "render_frames", "blur_margin_px",
]
