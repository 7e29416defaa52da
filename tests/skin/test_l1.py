"""L1 influence functions: exact adjoint identity, agreement with L2, extremes."""
import dataclasses

import numpy as np
import pytest
from scipy.sparse.linalg import splu

from feeler.models.skin import SkinParams, StepProfile, loading_history, strain_history
from feeler.models.skin.fem import finger_fem
from feeler.models.skin.l1 import influence
from feeler.models.skin.l2 import l2_strain_history
from tests.skin.conftest import SMALL

P = SkinParams()
DT = 2.5e-3  # s at 20 mm/s: 50 µm of travel per step


def _slide(level, profile, speed=20.0):
    fn = l2_strain_history if level == "l2" else None
    if fn:
        t, e = fn(profile, speed, params=P, mesh=SMALL, dt_s=DT * 20.0 / speed)
    else:
        t, e = strain_history(profile, speed, level=level, params=P, mesh=SMALL, dt_s=DT * 20.0 / speed)
    s = loading_history(P, speed, DT * 20.0 / speed).slide_start
    return t[s:], e[s:]


def test_one_adjoint_equals_schur_complement():
    fem = finger_fem(P, SMALL)
    inf = influence(P, SMALL)
    fixed = np.flatnonzero(np.isin(fem.surface_x_mm, inf.x_mm))
    a_dof = fem.contact_dof[fixed]
    f_dof = np.setdiff1d(fem.free, a_dof)
    k = fem.stiffness.tocsr()
    w = fem.corpuscle
    lam = splu(k[f_dof][:, f_dof].tocsc()).solve(w[f_dof])
    schur = w[a_dof] - k[a_dof][:, f_dof] @ lam
    np.testing.assert_allclose(inf.gain, schur, rtol=1e-7, atol=1e-9 * np.abs(schur).max())


def test_l1_matches_l2_on_a_small_mesh():
    prof = StepProfile(15.0)
    t, e2 = _slide("l2", prof)
    _, e1 = _slide("l1", prof)
    assert e1[0] == pytest.approx(e2[0], rel=1e-9)           # same pressed state
    step2, step1 = e2 - e2[0], e1 - e1[0]
    peak = np.max(np.abs(step2))
    assert np.max(np.abs(step1 - step2)) < 0.03 * peak    # contact set frozen in L1: 1.4 % seen
    r2, r1 = np.diff(e2) / np.diff(t), np.diff(e1) / np.diff(t)
    assert np.max(np.abs(r1)) == pytest.approx(np.max(np.abs(r2)), rel=0.10)


def test_linear_in_height_and_zero_step_flat():
    _, e10 = _slide("l1", StepProfile(10.0))
    _, e5 = _slide("l1", StepProfile(5.0))
    _, e0 = _slide("l1", StepProfile(0.0))
    np.testing.assert_allclose(e0, e0[0], rtol=1e-12)
    np.testing.assert_allclose(e10 - e0, 2 * (e5 - e0), rtol=1e-9, atol=1e-15)


def test_step_at_the_edge_of_the_contact_patch():
    inf = influence(P, SMALL)
    edge = P.slide_mm + inf.x_mm.max()          # the step stops at the patch edge
    prof = StepProfile(15.0, position_mm=edge)
    _, e2 = _slide("l2", prof)
    _, e1 = _slide("l1", prof)
    _, centre = _slide("l1", StepProfile(15.0))
    peak = np.max(np.abs(centre - centre[0]))
    assert np.all(np.isfinite(e2)) and np.all(np.isfinite(e1))
    assert np.max(np.abs(e2 - e2[0])) < 0.02 * peak
    assert np.max(np.abs((e1 - e1[0]) - (e2 - e2[0]))) < 0.01 * peak


@pytest.mark.parametrize("speed", [1.0, 200.0])
def test_speed_extremes_give_the_same_strain_against_travel(speed):
    t, e = strain_history(StepProfile(10.0), speed, level="l1", params=P, mesh=SMALL,
                          dt_s=0.05 / speed)
    _, ref = strain_history(StepProfile(10.0), 20.0, level="l1", params=P, mesh=SMALL,
                            dt_s=0.05 / 20.0)
    s = loading_history(P, speed, 0.05 / speed).slide_start
    s_ref = loading_history(P, 20.0, 0.05 / 20.0).slide_start
    np.testing.assert_allclose(e[s:], ref[s_ref:], rtol=1e-12)
    assert t[-1] == pytest.approx(P.press_s + P.hold_s + P.slide_mm / speed)


def test_pressed_contact_is_symmetric_and_compressive():
    inf = influence(P, SMALL)
    assert inf.pressed_eps < 0
    assert inf.x_mm.min() == pytest.approx(-inf.x_mm.max(), abs=SMALL.h_contact_mm)
    assert np.all(inf.contact_force_n_mm >= 0)


def test_vectorised_l1_matches_the_history_interface():
    from feeler.models.skin.l1 import l1_slide_strain
    t = np.linspace(0, 1.7, 700)
    out = l1_slide_strain(np.array([[5.0], [15.0]]), np.array([20.0, 40.0]), t, params=P, mesh=SMALL)
    assert out.shape == (2, 2, 700)
    for i, h in enumerate((5.0, 15.0)):
        for j, v in enumerate((20.0, 40.0)):
            ts, e = strain_history(StepProfile(h), v, level="l1", params=P, mesh=SMALL, dt_s=0.05 / v)
            s = loading_history(P, v, 0.05 / v).slide_start
            mine = l1_slide_strain(h, v, ts, params=P, mesh=SMALL)
            np.testing.assert_allclose(mine[s:], e[s:] - e[s], rtol=1e-9, atol=1e-14)
            np.testing.assert_allclose(out[i, j], l1_slide_strain(h, v, t, params=P, mesh=SMALL), rtol=1e-12)


def test_half_space_limit_matches_l0():
    # homogeneous skin, large finger: the step response tends to the half-space formula
    params = SkinParams(e_mpa=(0.05, 0.05, 0.05), radius_mm=20.0, press_mm=2.0)
    mesh = dataclasses.replace(SMALL, h_far_mm=3.0, contact_half_width_mm=15.0)
    t, e1 = strain_history(StepProfile(10.0), 20.0, level="l1", params=params, mesh=mesh, dt_s=DT)
    _, e0 = strain_history(StepProfile(10.0), 20.0, level="l0", params=params, dt_s=DT)
    s = loading_history(params, 20.0, DT).slide_start
    d1, d0 = e1[s:] - e1[s], e0[s:]
    assert np.ptp(d1) == pytest.approx(np.ptp(d0), rel=0.03)
    assert d1.max() == pytest.approx(d0.max(), rel=0.08)
    assert d1.min() == pytest.approx(d0.min(), rel=0.08)
    # the layered paper finger departs from it: the soft dermis under the stiff epidermis
    _, layered = _slide("l1", StepProfile(10.0))
    assert np.ptp(layered - layered[0]) > 1.2 * np.ptp(d0)


def test_l2_at_1_mm_s_is_the_elastic_l1():
    t, e2 = l2_strain_history(StepProfile(10.0), 1.0, params=P, mesh=SMALL, dt_s=0.1)
    _, e1 = strain_history(StepProfile(10.0), 1.0, level="l1", params=P, mesh=SMALL, dt_s=0.1)
    s = loading_history(P, 1.0, 0.1).slide_start
    peak = np.ptp(e2[s:])
    assert np.max(np.abs((e2[s:] - e2[s]) - (e1[s:] - e1[s]))) < 0.01 * peak
