"""Uncondensed reference for L2: per-triangle Prony internal variables, two full
sparse solves per step. Used only by the tests to check the exact condensation."""
import numpy as np

from feeler.models.skin.contact import solve_contact
from feeler.models.skin.fem import finger_fem
from feeler.models.skin.l2 import plate_need_mm, prony_factors
from feeler.models.skin.loading import loading_history

__all__ = ["full_field_l2"]


def full_field_l2(profile, speed_mm_s, *, params, mesh, dt_s):
    fem = finger_fem(params, mesh)
    load = loading_history(params, speed_mm_s, dt_s)
    n_tri = fem.mesh.triangles.shape[1]
    weighted_d = fem.elastic * fem.area_mm2[:, None, None]
    s, eps_prev = np.zeros((n_tri, 3)), np.zeros((n_tri, 3))
    out, active, g1 = np.zeros(len(load.t_s)), None, params.prony_ratio
    for n in range(1, len(load.t_s)):
        decay, gamma, c = prony_factors(load.t_s[n] - load.t_s[n - 1], params)
        hist = g1 * (decay * s - gamma * eps_prev)
        f_hist = -(fem.strain.T @ np.einsum("eij,ej->ei", weighted_d, hist).ravel())
        u_free = fem.solve(f_hist) / c
        need = plate_need_mm(fem, profile, load.press_mm[n], load.travel_mm[n]) - u_free[fem.contact_dof]
        p, active = solve_contact(fem.compliance / c, need, active)
        rhs = np.zeros(len(u_free))
        rhs[fem.contact_dof] = p
        u = u_free + fem.solve(rhs) / c
        eps = (fem.strain @ u).reshape(n_tri, 3)
        s = decay * s + gamma * (eps - eps_prev)
        eps_prev = eps
        out[n] = fem.corpuscle @ u
    return load.t_s, out
