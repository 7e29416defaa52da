"""L2: viscoelastic plane-strain contact FEM of the pressed and sliding finger.

The finger is fixed; the rigid plate moves under it (press ``press_mm`` in ``press_s``,
hold ``hold_s``, slide ``slide_mm`` at the speed). Each time step:

1. first-order Prony viscoelasticity, σ = D0 [(1−g1) ε + g1 s] with the internal
   variable s per triangle, s_n = e^{−Δ/τ} s_{n−1} + γ (ε_n − ε_{n−1}),
   γ = (τ/Δ)(1 − e^{−Δ/τ}) (exact for strain linear within the step). The history part
   is a load, the effective stiffness is c K0 with c = 1 − g1 + g1 γ: K0 is factorised
   once for every time step;
2. frictionless contact with the stepped plate, condensed exactly onto the y-DOFs of
   the contact-strip nodes (compliance C0 / c), solved by an active set;
3. the full displacement field, the strain per triangle, and the corpuscle average ε̄_y.

The sign convention is the paper's: ε_y positive in tension along the surface normal.
"""
from __future__ import annotations

import numpy as np

from feeler.errors import ArgumentError
from feeler.models.skin.contact import single_thread_blas, solve_contact
from feeler.models.skin.fem import FingerFEM, finger_fem
from feeler.models.skin.loading import loading_history
from feeler.models.skin.mesh import MeshSpec
from feeler.models.skin.params import SkinParams, StepProfile

__all__ = ["plate_need_mm", "l2_strain_history", "check_patch_inside_strip"]


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
    state = _Prony(fem, params)
    active = None
    out = np.zeros(len(load.t_s))
    with single_thread_blas():
        for n in range(1, len(load.t_s)):
            c, u_free = state.begin(load.t_s[n] - load.t_s[n - 1])
            need = plate_need_mm(fem, profile, load.press_mm[n], load.travel_mm[n]) - u_free[fem.contact_dof]
            p, active = solve_contact(fem.compliance / c, need, active)
            check_patch_inside_strip(active, spec)
            rhs = np.zeros(len(u_free))
            rhs[fem.contact_dof] = p
            u = u_free + fem.solve(rhs) / c
            state.end(u)
            out[n] = fem.corpuscle @ u
            if record is not None:
                record.append(p)
    return load.t_s, out


class _Prony:
    """Internal variables of the first-order Prony series, one strain-like triple per triangle."""

    def __init__(self, fem: FingerFEM, params: SkinParams):
        n_tri = fem.mesh.triangles.shape[1]
        self.fem, self.g1, self.tau = fem, params.prony_ratio, params.prony_tau_s
        self.weighted_d = fem.elastic * fem.area_mm2[:, None, None]
        self.s = np.zeros((n_tri, 3))
        self.eps = np.zeros((n_tri, 3))
        self.decay = self.gamma = 1.0

    def begin(self, dt: float):
        """Step factors for a step of ``dt`` s: (c, u_free) with c K0 u = f_hist + contact."""
        self.decay = np.exp(-dt / self.tau)
        self.gamma = -np.expm1(-dt / self.tau) * self.tau / dt
        c = 1.0 - self.g1 + self.g1 * self.gamma
        hist = self.g1 * (self.decay * self.s - self.gamma * self.eps)
        f_hist = -(self.fem.strain.T @ np.einsum("eij,ej->ei", self.weighted_d, hist).ravel())
        return c, self.fem.solve(f_hist) / c

    def end(self, u: np.ndarray) -> None:
        """Update the internal variables with the converged displacement u (ndarray[n_dof])."""
        eps = (self.fem.strain @ u).reshape(self.s.shape)
        self.s = self.decay * self.s + self.gamma * (eps - self.eps)
        self.eps = eps
