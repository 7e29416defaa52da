"""L0: closed-form plane-strain half-space response to a surface displacement step.

A frictionless surface displacement step of height h at x_step (raised side ξ > 0,
pushed into the skin) gives, at depth z below the surface,

    Δε_y(ξ, z) = −(h / (2π(1−ν))) · ξ · [(1−2ν)/(ξ²+z²) + 2z²/(ξ²+z²)²],  ξ = x − x_step

(y into the skin, compression < 0). Its depth integral is −(h/2)·sign ξ: the surface
moves by ±h/2 about the far field. The corpuscle average over the w × d element is exact,
from the antiderivative

    F(ξ, z) = (1−2ν)/2 · [z ln(ξ²+z²) − 2z + 2ξ atan(z/ξ)] − z + ξ atan(z/ξ),

whose mixed second derivative is the bracketed term times ξ. A rounded edge (linear ramp
of width e) is the average of the step response over the ramp, exact again through
G = ∫ F dξ (eight evaluations of G per sample).

In L0 the press is a linear ramp of the base shift (L0 models the slide only).
Optionally scaled by a layering gain and shifted by the pressed-state strain (constants
fitted to an L2 run, see :func:`fit_l0`).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from feeler.models.skin.loading import loading_history
from feeler.models.skin.params import SkinParams, StepProfile

__all__ = ["halfspace_strain", "step_kernel", "l0_slide_strain", "l0_strain_history", "fit_l0"]


def halfspace_strain(xi_mm, depth_mm, nu: float):
    """The point formula Δε_y / h at (ξ, z) (1/mm; ndarray broadcast of the inputs)."""
    xi, z = np.asarray(xi_mm, dtype=float), np.asarray(depth_mm, dtype=float)
    r2 = xi * xi + z * z
    return -xi * ((1 - 2 * nu) / r2 + 2 * z * z / (r2 * r2)) / (2 * np.pi * (1 - nu))


def _antiderivative(xi, z, nu):
    """F(ξ, z) with ∂²F/∂ξ∂z = ξ[(1−2ν)/(ξ²+z²) + 2z²/(ξ²+z²)²] (z > 0), using
    ξ atan(z/ξ) = (π/2)|ξ| − ξ atan(ξ/z) so that F is smooth through ξ = 0."""
    a = 0.5 * np.pi * np.abs(xi) - xi * np.arctan(xi / z)
    return 0.5 * (1 - 2 * nu) * z * np.log(xi * xi + z * z) + (2 - 2 * nu) * (a - z)


def _antiderivative2(xi, z, nu):
    """G(ξ, z) = ∫ F dξ, for the exact average over a linear ramp edge."""
    r2 = xi * xi + z * z
    at = np.arctan(xi / z)
    log_part = z * (xi * np.log(r2) - 2 * xi + 2 * z * at)
    a_part = 0.25 * np.pi * xi * np.abs(xi) - 0.5 * r2 * at + 0.5 * z * xi
    return 0.5 * (1 - 2 * nu) * log_part + (2 - 2 * nu) * (a_part - z * xi)


def step_kernel(xi_mm, params: SkinParams, edge_um: float = 0.0):
    """Corpuscle-averaged strain per unit step height (ε_y per mm of step), exact.

    Args:
        xi_mm (ndarray[...]): corpuscle centre minus step centre along x, mm.
        params: ν and the corpuscle element (width, height, centre depth).
        edge_um (float): width of the step's linear ramp in µm (0 = sharp); the ramp is
            averaged exactly with the second antiderivative.
    Returns:
        ndarray[...]: Δε_y / h (1/mm), without the L0 gain.
    """
    xi = np.asarray(xi_mm, dtype=float)
    nu, w, d = params.nu, params.corpuscle_width_mm, params.corpuscle_height_mm
    z1 = params.corpuscle_depth_mm - d / 2
    total = np.zeros(np.shape(xi))
    e = edge_um * 1e-3
    for sx, dx in ((1.0, w / 2), (-1.0, -w / 2)):
        for sz, z in ((1.0, z1 + d), (-1.0, z1)):
            if e > 0:
                corner = (_antiderivative2(xi + dx + e / 2, z, nu)
                          - _antiderivative2(xi + dx - e / 2, z, nu)) / e
            else:
                corner = _antiderivative(xi + dx, z, nu)
            total += sx * sz * corner
    return -total / (2 * np.pi * (1 - nu) * w * d)


def l0_slide_strain(step_um, speed_mm_s, t_s, *, params: SkinParams,
                    position_mm: float = 5.0, edge_um: float = 50.0, t0_s: float | None = None):
    """Vectorised L0 slide: Δε_y for many step heights, speeds and times at once.

    Args:
        step_um (ndarray[...]): step heights in µm (broadcast against ``speed_mm_s``).
        speed_mm_s (ndarray[...]): sliding speeds in mm/s, > 0.
        t_s (ndarray[n_time]): times in seconds.
        params: ν, corpuscle, slide length and the L0 gain.
        position_mm (float): step centre on the plate, mm.
        edge_um (float): ramp width of the step's edge, µm.
        t0_s (float | None): start of the slide; None → press_s + hold_s.
    Returns:
        ndarray[..., n_time]: gain · Δε_y (no base shift); travel stops at slide_mm.
    """
    t0 = params.press_s + params.hold_s if t0_s is None else t0_s
    step = np.asarray(step_um, dtype=float)[..., None]
    speed = np.asarray(speed_mm_s, dtype=float)[..., None]
    travel = np.clip((np.asarray(t_s, dtype=float) - t0) * speed, 0.0, params.slide_mm)
    return params.l0_gain * step * 1e-3 * step_kernel(travel - position_mm, params, edge_um)


def l0_strain_history(profile: StepProfile, speed_mm_s: float, *, params: SkinParams,
                      dt_s: float | None = None):
    """L0 strain history on the common press–hold–slide grid.

    Returns:
        (t_s ndarray[n_time], eps_y ndarray[n_time]): the base shift ramps in with the
        press, then the step response is added along the slide.
    """
    load = loading_history(params, speed_mm_s, dt_s)
    base = params.l0_base * load.press_mm / params.press_mm
    kern = step_kernel(load.travel_mm - profile.position_mm, params, profile.edge_um)
    return load.t_s, base + params.l0_gain * profile.height_um * 1e-3 * kern


def fit_l0(profile: StepProfile, eps_ref, load_travel_mm, *, params: SkinParams):
    """Least-squares gain and base shift of L0 against a reference slide (e.g. L2).

    Args:
        profile: the step of the reference run.
        eps_ref (ndarray[n]): reference strain during the slide.
        load_travel_mm (ndarray[n]): finger travel of those samples, mm.
    Returns:
        SkinParams: ``params`` with ``l0_gain`` and ``l0_base`` replaced.
    """
    kern = profile.height_um * 1e-3 * step_kernel(np.asarray(load_travel_mm) - profile.position_mm,
                                                  params, profile.edge_um)
    design = np.column_stack([kern, np.ones_like(kern)])
    (gain, base), *_ = np.linalg.lstsq(design, np.asarray(eps_ref, dtype=float), rcond=None)
    return dataclasses.replace(params, l0_gain=float(gain), l0_base=float(base))
