"""L2 FEM: closed-form elasticity (2-D Hertz), viscoelastic exact limits, mesh errors."""
import dataclasses

import numpy as np
import pytest
import scipy.sparse as sp

import feeler.models.skin.mesh as mesh_mod
from feeler.errors import ArgumentError
from feeler.models.skin import SkinParams, StepProfile, loading_history
from feeler.models.skin.contact import solve_contact
from feeler.models.skin.fem import finger_fem
from feeler.models.skin.l2 import l2_strain_history, plate_need_mm, prony_factors
from feeler.models.skin.mesh import MeshSpec, finger_mesh
from tests.skin.conftest import COARSE_DT, HERTZ, SMALL

P = SkinParams()


def test_scikit_fem_stiffness_equals_strain_operator_form():
    fem = finger_fem(P, SMALL)
    blocks = sp.block_diag([sp.csr_matrix(a * d) for a, d in zip(fem.area_mm2, fem.elastic)])
    k = fem.strain.T @ blocks @ fem.strain
    assert abs(k - fem.stiffness).max() < 1e-12 * abs(fem.stiffness).max()


def test_mesh_regions_and_corpuscle_functional():
    fem = finger_fem(P, SMALL)
    m = fem.mesh
    assert set(np.unique(m.layer)) == {0, 1, 2}
    area = fem.area_mm2[m.corpuscle].sum()
    assert area == pytest.approx(P.corpuscle_width_mm * P.corpuscle_height_mm, rel=1e-9)
    # a uniform vertical stretch u_y = k (y − R) gives ε_y = k exactly in the corpuscle
    u = np.zeros(2 * m.n_nodes)
    u[1::2] = 0.01 * (m.points[1] - P.radius_mm)
    assert fem.corpuscle @ u == pytest.approx(0.01, rel=1e-12)
    assert np.all(np.diff(fem.surface_x_mm) > 0)


@pytest.mark.parametrize("press_mm", [0.05, 0.1])
def test_pressed_state_matches_2d_hertz(press_mm):
    e = 0.05
    params = SkinParams(e_mpa=(e, e, e), press_mm=press_mm)
    fem = finger_fem(params, HERTZ)
    p, active = solve_contact(fem.compliance, plate_need_mm(fem, None, press_mm, 0.0))
    x, load = fem.surface_x_mm, p.sum()
    a = np.sqrt(4 * (x * x * p).sum() / load)           # second moment of an ellipse: a²/4
    e_star = e / (1 - params.nu ** 2)
    a_hertz = np.sqrt(4 * load * params.radius_mm / (np.pi * e_star))
    assert a == pytest.approx(a_hertz, rel=0.02)
    # elliptical pressure: nodal force / tributary width against p0 sqrt(1 − x²/a²)
    width = np.gradient(x)
    p0 = 2 * load / (np.pi * a_hertz)
    inner = np.abs(x) < 0.8 * a_hertz
    shape = p0 * np.sqrt(1 - (x[inner] / a_hertz) ** 2)
    assert np.max(np.abs(p[inner] / width[inner] - shape)) < 0.05 * p0
    assert np.max(np.abs(x[active])) == pytest.approx(a_hertz, abs=2 * HERTZ.h_contact_mm)


def test_hold_under_displacement_control_keeps_strain_and_relaxes_force():
    # same Prony ratio everywhere: strains are rate-independent, forces relax to (1 − g1)
    forces = []
    t, eps = l2_strain_history(StepProfile(0.0), 20.0, params=P, mesh=SMALL, dt_s=2.5e-3,
                               record=forces)
    load = loading_history(P, 20.0, 2.5e-3)
    end_press, end_hold = 20, load.slide_start
    assert eps[end_hold] == pytest.approx(eps[end_press], rel=1e-9)
    fem = finger_fem(P, SMALL)
    p_el, _ = solve_contact(fem.compliance, plate_need_mm(fem, None, P.press_mm, 0.0))
    assert forces[end_hold - 1].sum() == pytest.approx((1 - P.prony_ratio) * p_el.sum(), rel=1e-6)
    # at the end of the press ramp the force exceeds the linear-ramp value
    # g∞ + g1 (τ/T)(1 − e^{−T/τ}) (the contact set grows, so the elastic force is convex in t)
    tau, g1, ramp = P.prony_tau_s, P.prony_ratio, P.press_s
    linear = 1 - g1 + g1 * tau / ramp * (1 - np.exp(-ramp / tau))
    assert linear < forces[end_press - 1].sum() / p_el.sum() < linear + 0.05
    # a flat plate sliding without friction changes nothing
    np.testing.assert_allclose(eps[end_hold:], eps[end_hold], rtol=1e-9)


@pytest.mark.parametrize("tau_s, ratio", [(1e-3, 0.5), (10.0, 1.0)])
def test_prony_time_constant_extremes(tau_s, ratio):
    params = dataclasses.replace(P, prony_tau_s=tau_s, hold_s=0.0)
    forces = []
    l2_strain_history(StepProfile(0.0), 200.0, params=params, mesh=SMALL, record=forces,
                      dt_s=0.01)
    fem = finger_fem(params, SMALL)
    p_el, _ = solve_contact(fem.compliance, plate_need_mm(fem, None, P.press_mm, 0.0))
    assert forces[19].sum() / p_el.sum() == pytest.approx(ratio, abs=0.02)


def test_step_response_nearly_speed_independent():
    runs = {}
    for v in (20.0, 40.0):
        t, e = l2_strain_history(StepProfile(15.0), v, params=P, mesh=SMALL, dt_s=COARSE_DT / v)
        s = loading_history(P, v, COARSE_DT / v).slide_start
        runs[v] = e[s:] - e[s]
    peak = np.max(np.abs(runs[20.0]))
    diff = np.max(np.abs(runs[20.0] - runs[40.0]))
    assert peak > 0.008
    assert diff < 0.02 * peak


def test_coarse_corpuscle_mesh_is_an_error():
    with pytest.raises(ArgumentError, match="too coarse for the 40 × 50 µm corpuscle"):
        l2_strain_history(StepProfile(10.0), 20.0, params=P,
                          mesh=dataclasses.replace(SMALL, h_corpuscle_mm=0.03))
    with pytest.raises(ArgumentError, match="mesh.h_contact_mm"):
        finger_mesh(P, dataclasses.replace(SMALL, h_contact_mm=0.2))
    with pytest.raises(ArgumentError, match="mesh.grade"):
        finger_mesh(P, dataclasses.replace(SMALL, grade=0.0))
    with pytest.raises(ArgumentError, match="contact_half_width"):
        finger_mesh(P, dataclasses.replace(SMALL, contact_half_width_mm=8.0))


def test_too_few_corpuscle_triangles_is_an_error(monkeypatch):
    monkeypatch.setattr(mesh_mod, "MIN_CORPUSCLE_TRIANGLES", 10_000)
    mesh_mod._mesh_cached.cache_clear()
    try:
        with pytest.raises(ArgumentError, match="triangles in the corpuscle"):
            finger_mesh(P, SMALL)
    finally:
        mesh_mod._mesh_cached.cache_clear()


def test_contact_patch_wider_than_strip_is_an_error():
    narrow = dataclasses.replace(SMALL, contact_half_width_mm=1.0, band_half_width_mm=0.8)
    with pytest.raises(ArgumentError, match="edge of the candidate strip"):
        l2_strain_history(StepProfile(10.0), 20.0, params=P, mesh=narrow, dt_s=1.0)


def test_condensed_l2_equals_full_field_with_per_triangle_internal_variables():
    prof = StepProfile(15.0, position_mm=3.0)
    params = dataclasses.replace(P, slide_mm=4.0, hold_s=0.05)
    t, fast = l2_strain_history(prof, 40.0, params=params, mesh=SMALL, dt_s=2e-3)
    _, ref = full_field_l2(prof, 40.0, params=params, mesh=SMALL, dt_s=2e-3)
    np.testing.assert_allclose(fast, ref, rtol=1e-8, atol=1e-12)


# Uncondensed reference for L2: per-triangle Prony internal variables, two full sparse
# solves per step -- checks that the condensation onto the contact nodes is exact.
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
