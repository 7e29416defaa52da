"""L1: influence functions from one adjoint solve about the pressed state.

In the pressed state (flat plate, press_mm; elastic = viscoelastic after the hold under
displacement control) the contact set A is found by the condensed active-set solver.
Prescribing the y-displacements of the contact nodes, the corpuscle strain is linear in
them: ε̄_y = G·u_A. With the factorised K0 (flat face clamped) and the condensed
compliance C0, one adjoint solve λ = K0⁻¹ w gives the sensitivity

    G = (C0)_AA⁻¹ λ_A        (exactly the Schur complement w_A − K_AF K_FF⁻¹ w_F)

of the corpuscle strain to every contact node's displacement. A slide is then one dot
product per position: ε̄_y(t) = G·need_A(t), with need the plate height averaged over
each node's hat (as in L2). The contact set is frozen at the pressed state, and moduli
cancel (only their ratios matter): this is the linearisation of L2 about the press.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from feeler.models.skin.contact import single_thread_blas, solve_contact
from feeler.models.skin.fem import finger_fem
from feeler.models.skin.l2 import check_patch_inside_strip, plate_need_mm
from feeler.models.skin.loading import loading_history
from feeler.models.skin.mesh import MeshSpec
from feeler.models.skin.params import SkinParams, StepProfile

__all__ = ["Influence", "influence", "l1_strain_history", "l1_slide_strain"]


@dataclass(frozen=True, eq=False)
class Influence:
    """The corpuscle's influence function about the pressed state.

    Attributes:
        x_mm (ndarray[n_a]): contact-node positions in the finger frame, mm.
        y_mm (ndarray[n_a]): their undeformed heights above the lowest point, mm.
        gain (ndarray[n_a]): G, ε̄_y per mm of upward displacement of each node.
        pressed_eps (float): ε̄_y in the pressed state.
        contact_force_n_mm (ndarray[n_a]): pressed-state contact forces, N per mm length.
    """

    x_mm: np.ndarray
    y_mm: np.ndarray
    gain: np.ndarray
    pressed_eps: float
    contact_force_n_mm: np.ndarray

    def strain(self, profile: StepProfile | None, press_mm: float, travel_mm) -> np.ndarray:
        """ε̄_y for the plate at ``press_mm`` and travels ``travel_mm`` (ndarray[n]) → [n]."""
        travel = np.atleast_1d(np.asarray(travel_mm, dtype=float))
        rows = np.full((len(travel), len(self.x_mm)), press_mm) - self.y_mm
        if profile is not None:
            rows += profile.hat_average_mm(self.x_mm, travel)
        return rows @ self.gain


def influence(params: SkinParams, spec: MeshSpec | None = None) -> Influence:
    """Pressed state and influence function for ``params`` on the mesh ``spec`` (cached)."""
    return _influence_cached(params, MeshSpec() if spec is None else spec)


@functools.lru_cache(maxsize=8)
def _influence_cached(params: SkinParams, spec: MeshSpec) -> Influence:
    fem = finger_fem(params, spec)
    with single_thread_blas():
        need = params.press_mm - fem.surface_y_mm
        p, active = solve_contact(fem.compliance, need)
        check_patch_inside_strip(active, spec)
        adjoint = fem.solve(fem.corpuscle)[fem.contact_dof]          # the one adjoint solve
        idx = np.flatnonzero(active)
        gain = np.linalg.solve(fem.compliance[np.ix_(idx, idx)], adjoint[idx])
    return Influence(x_mm=fem.surface_x_mm[idx], y_mm=fem.surface_y_mm[idx], gain=gain,
                     pressed_eps=float(gain @ need[idx]), contact_force_n_mm=p[idx])


def l1_strain_history(profile: StepProfile, speed_mm_s: float, *, params: SkinParams,
                      dt_s: float | None = None, mesh: MeshSpec | None = None):
    """L1 strain history on the common loading grid.

    The press phase is a linear ramp to the pressed strain (L1 models the slide; the
    press is nonlinear in the contact set), then ε̄_y = G·need along the slide.
    Returns (t_s ndarray[n_time], eps_y ndarray[n_time]).
    """
    load = loading_history(params, speed_mm_s, dt_s)
    inf = influence(params, mesh)
    eps = inf.pressed_eps * load.press_mm / params.press_mm
    sl = slice(load.slide_start, None)
    eps[sl] = inf.strain(profile, params.press_mm, load.travel_mm[sl])
    return load.t_s, eps


def l1_slide_strain(step_um, speed_mm_s, t_s, *, params: SkinParams, mesh: MeshSpec | None = None,
                    position_mm: float = 5.0, edge_um: float = 50.0, t0_s: float | None = None):
    """Vectorised L1 slide, like :func:`feeler.models.skin.l0.l0_slide_strain`.

    Args:
        step_um (ndarray[...]): step heights in µm (broadcast against ``speed_mm_s``).
        speed_mm_s (ndarray[...]): sliding speeds in mm/s, > 0.
        t_s (ndarray[n_time]): times in seconds.
        t0_s (float | None): start of the slide; None → press_s + hold_s.
    Returns:
        ndarray[..., n_time]: Δε_y from the pressed state (linear in the step height).
    """
    inf = influence(params, mesh)
    t0 = params.press_s + params.hold_s if t0_s is None else t0_s
    step, speed = np.broadcast_arrays(np.asarray(step_um, dtype=float), np.asarray(speed_mm_s, dtype=float))
    unit = StepProfile(1.0, position_mm, edge_um)
    out = np.empty(step.shape + (len(np.atleast_1d(t_s)),))
    for v in np.unique(speed):
        travel = np.clip((np.asarray(t_s, dtype=float) - t0) * v, 0.0, params.slide_mm)
        response = unit.hat_average_mm(inf.x_mm, travel) @ inf.gain
        mask = speed == v
        out[mask] = step[mask][:, None] * response
    return out
