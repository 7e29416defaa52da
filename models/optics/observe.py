"""The `areas` fidelity of the optical sensor: U → F → areas (+ noise, quantised) → F̂ → Û."""
from __future__ import annotations

import numpy as np

from feeler.errors import ArgumentError

from .law import (OpticsParams, areas_from_force, displacement_from_force, force_from_areas,
                  force_from_displacement)

__all__ = ["observe_areas", "measure_areas"]


def measure_areas(areas_px2: np.ndarray, params: OpticsParams, rng: np.random.Generator) -> np.ndarray:
    """Areas as measured: true areas plus white noise (``area_sd_px2``), quantised to
    ``area_step_px2`` and clipped at 0. Shape preserved (..., 4), px²."""
    measured = np.asarray(areas_px2, float) + rng.normal(0.0, params.area_sd_px2, np.shape(areas_px2))
    if params.area_step_px2 > 0:
        measured = np.rint(measured / params.area_step_px2) * params.area_step_px2
    return np.maximum(measured, 0.0)


def observe_areas(u_mm: np.ndarray, *, params: OpticsParams, rng: np.random.Generator) -> np.ndarray:
    """Measured tip displacement at the `areas` fidelity.

    The true displacement is turned into the element's force F = C⁻¹ U, the four contact
    areas by the area law, measured with noise and quantisation, inverted back to force and
    mapped to displacement through the same C.

    Args:
        u_mm (ndarray[..., n_time, 3]): true tip displacement (mm), order (x, y, z).
        params (OpticsParams): the element and its area noise.
        rng (numpy.random.Generator): the noise source.

    Returns:
        ndarray[..., n_time, 3]: measured displacement (mm), same shape as ``u_mm``.

    Raises:
        ArgumentError: a bad shape, non-finite values, or a displacement outside the
            element's measuring range (negative contact area).
    """
    u = np.asarray(u_mm, dtype=float)
    if u.ndim < 2 or u.shape[-1] != 3:
        raise ArgumentError("u_mm", f"array of shape {u.shape}", "shape (..., n_time, 3)")
    if not np.all(np.isfinite(u)):
        raise ArgumentError("u_mm", "non-finite values", "finite displacements (mm)")
    c = params.c_matrix
    areas = areas_from_force(force_from_displacement(u, c), params)
    measured = measure_areas(areas, params, rng)
    return displacement_from_force(force_from_areas(measured, params), c)
