"""L2: viscoelastic plane-strain contact FEM of the pressed and sliding finger.

The finger is fixed; the rigid plate moves under it (press ``press_mm`` in ``press_s``,
hold ``hold_s``, slide ``slide_mm`` at the speed). Material: first-order Prony series
with one ratio g1 and time constant τ for all layers (the paper's assumption),
σ = D0 [(1−g1) ε + g1 s], s_n = e^{−Δ/τ} s_{n−1} + γ (ε_n − ε_{n−1}),
γ = (τ/Δ)(1 − e^{−Δ/τ}) (exact for strain linear within a step).

Because s is the same linear filter of ε in every triangle and ε = B u, the internal
variables are exactly s = B q with the filtered nodal displacement q; the history load
is −g1 K0 (e^{−Δ/τ} q − γ u_{n−1}), so with the effective stiffness c K0,
c = 1 − g1 + g1 γ, the contact-free displacement is u_free = −g1 (e^{−Δ/τ} q − γ u_{n−1}) / c
without a solve. Everything then condenses exactly onto the contact DOFs:

    u_c = u_free,c + C0 p / c,       ε̄_y = w·u_free + λ_c·p / c,

with C0 = (K0⁻¹)_cc and λ = K0⁻¹ w (one adjoint solve), and the frictionless contact
forces p ≥ 0 come from the active-set solver each step. The internal variables carried
per step are q at the contact DOFs and w·q at the corpuscle. (The equivalence with
per-triangle internal variables and full-field solves is tested.)
"""
from __future__ import annotations

import numpy as np

from feeler.errors import ArgumentError
from feeler.models.skin.contact import single_thread_blas, solve_contact
from feeler.models.skin.fem import FingerFEM, finger_fem
from feeler.models.skin.loading import loading_history
from feeler.models.skin.mesh import MeshSpec
from feeler.models.skin.params import SkinParams, StepProfile

__all__ = ["plate_need_mm", "l2_strain_history", "check_patch_inside_strip", "prony_factors"]


def plate_need_mm(fem: FingerFEM, profile: StepProfile | None, press_mm: float, travel_mm: float):
    """Upward displacement (mm) each contact-strip node needs to sit on the plate.

    The plate's top is at press + height(x + travel) in finger coordinates; a node at
    height Y touches when Y + u_y = that level. The height is averaged over each node's
    P1 hat function (weighted gap): a step then moves the nodes' targets smoothly, so the
    strain rate does not alias the node spacing.
    """
    level = press_mm + (0.0 if profile is None else profile.hat_average_mm(fem.surface_x_mm, travel_mm))
    return level - fem.surface_y_mm


def check_patch_inside_strip(active: np.ndarray, spec: MeshSpec) -> None:
    """The contact patch must end inside the candidate strip, else the contact is cut."""
    if active[0] or active[-1]:
        raise ArgumentError("mesh.contact_half_width_mm", spec.contact_half_width_mm,
                            "the contact patch reaches the edge of the candidate strip; widen it")


def prony_factors(dt_s: float, params: SkinParams) -> tuple[float, float, float]:
    """(decay e^{−Δ/τ}, γ, c = 1 − g1 + g1 γ) for a time step of ``dt_s`` seconds."""
    tau, g1 = params.prony_tau_s, params.prony_ratio
    decay = np.exp(-dt_s / tau)
    gamma = -np.expm1(-dt_s / tau) * tau / dt_s
    return decay, gamma, 1.0 - g1 + g1 * gamma


def l2_strain_history(profile: StepProfile, speed_mm_s: float, *, params: SkinParams,
                      dt_s: float | None = None, mesh: MeshSpec | None = None,
                      record: list | None = None):
    """L2 strain history ε̄_y(t) at the corpuscle on the common loading grid.

    Args:
        profile: the step on the plate.
        speed_mm_s (float): sliding speed, mm/s.
        params: material, geometry, loading.
        dt_s (float | None): slide time step in s (None → 10 µm of travel per step).
        mesh: element sizes (default :class:`MeshSpec`).
        record (list | None): if given, receives per step the contact forces p (N/mm).
    Returns:
        (t_s ndarray[n_time], eps_y ndarray[n_time])
    """
    spec = MeshSpec() if mesh is None else mesh
    load = loading_history(params, speed_mm_s, dt_s)
    fem = finger_fem(params, spec)
    g1 = params.prony_ratio
    n_c = len(fem.contact_dof)
    q_c, u_c = np.zeros(n_c), np.zeros(n_c)      # filtered and current contact displacements
    q_w = eps = 0.0                                # the same two at the corpuscle (w·q, w·u)
    active = None
    out = np.zeros(len(load.t_s))
    with single_thread_blas():
        for n in range(1, len(load.t_s)):
            decay, gamma, c = prony_factors(load.t_s[n] - load.t_s[n - 1], params)
            free_c = -g1 * (decay * q_c - gamma * u_c) / c
            free_w = -g1 * (decay * q_w - gamma * eps) / c
            need = plate_need_mm(fem, profile, load.press_mm[n], load.travel_mm[n]) - free_c
            p, active = solve_contact(fem.compliance / c, need, active)
            check_patch_inside_strip(active, spec)
            u_new = free_c + fem.compliance @ p / c
            eps_new = free_w + fem.adjoint @ p / c
            q_c = decay * q_c + gamma * (u_new - u_c)
            q_w = decay * q_w + gamma * (eps_new - eps)
            u_c, eps = u_new, eps_new
            out[n] = eps
            if record is not None:
                record.append(p)
    return load.t_s, out
