"""L0 closed form: exact cases, symmetry, sign, decay, quadrature cross-checks."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy import integrate

from feeler.errors import ArgumentError
from feeler.models.skin import SkinParams, StepProfile, loading_history, strain_history
from feeler.models.skin.l0 import fit_l0, halfspace_strain, l0_slide_strain, step_kernel

P = SkinParams()


def test_average_matches_dense_quadrature_of_point_formula():
    p = P
    for xi in (-1.3, -0.21, 0.0, 0.013, 0.4, 3.0):
        z1 = p.corpuscle_depth_mm - p.corpuscle_height_mm / 2
        val, _ = integrate.dblquad(lambda z, x: halfspace_strain(x, z, p.nu),
                                   xi - p.corpuscle_width_mm / 2, xi + p.corpuscle_width_mm / 2,
                                   z1, z1 + p.corpuscle_height_mm, epsabs=1e-13, epsrel=1e-11)
        mean = val / (p.corpuscle_width_mm * p.corpuscle_height_mm)
        assert step_kernel(xi, p) == pytest.approx(mean, rel=1e-8, abs=1e-12)


def test_depth_integral_is_half_the_step():
    # ∫_0^∞ Δε_y dz = −(h/2) sign ξ: the surface moves ±h/2 about the far field.
    for xi in (-0.7, 0.05, 2.0):
        val, _ = integrate.quad(lambda z: halfspace_strain(xi, z, 0.3), 0, np.inf, limit=200)
        assert val == pytest.approx(-0.5 * np.sign(xi), rel=1e-7)


@settings(max_examples=40, deadline=None)
@given(xi=st.floats(-20, 20), nu=st.floats(0.0, 0.49))
def test_odd_in_xi(xi, nu):
    p = SkinParams(nu=nu)
    assert step_kernel(-xi, p) == pytest.approx(-step_kernel(xi, p), abs=1e-12)


def test_sign_raised_side_compressed_and_zero_at_the_step():
    assert step_kernel(0.3, P) < 0 < step_kernel(-0.3, P)
    assert step_kernel(0.0, P) == pytest.approx(0.0, abs=1e-14)


def test_decay_one_over_xi():
    xi = np.array([50.0, 100.0, 200.0])
    limit = -(1 - 2 * P.nu) / (2 * np.pi * (1 - P.nu))
    scaled = xi * step_kernel(xi, P)
    np.testing.assert_allclose(scaled, limit, rtol=3e-3)
    excess = scaled - limit  # the next term falls as 1/ξ²
    np.testing.assert_allclose(excess[:-1] / excess[1:], 4.0, rtol=0.01)


def test_zero_step_gives_zero_and_linear_in_height():
    t = np.linspace(0, 2, 200)
    z = l0_slide_strain(0.0, 20.0, t, params=P)
    assert np.all(z == 0)
    a = l0_slide_strain(np.array([5.0, 10.0]), 20.0, t, params=P)
    np.testing.assert_allclose(a[1], 2 * a[0], rtol=1e-12)


def test_vectorised_shapes_and_speed_only_rescales_time():
    t = np.linspace(0, 2, 500)
    out = l0_slide_strain(np.array([5.0, 10.0, 15.0])[:, None], np.array([20.0, 40.0]), t, params=P)
    assert out.shape == (3, 2, 500)
    t0 = P.press_s + P.hold_s
    slow = l0_slide_strain(10.0, 20.0, t0 + (t - t0) * 2, params=P)
    fast = l0_slide_strain(10.0, 40.0, t, params=P)
    np.testing.assert_allclose(slow, fast, atol=1e-15)


def test_rounded_edge_is_invisible_at_corpuscle_depth():
    xi = np.linspace(-1.5, 1.5, 3001)
    sharp, round_ = step_kernel(xi, P, 0.0), step_kernel(xi, P, 50.0)
    assert np.max(np.abs(round_ - sharp)) < 0.005 * np.max(np.abs(sharp))


def test_history_interface_gain_and_base():
    params = SkinParams(l0_gain=2.0, l0_base=-0.1)
    t, e = strain_history(StepProfile(10.0), 20.0, level="l0", params=params)
    t1, e1 = strain_history(StepProfile(10.0), 20.0, level="l0")
    load = loading_history(params, 20.0)
    np.testing.assert_array_equal(t, load.t_s)
    assert np.all(np.diff(t) > 0)
    np.testing.assert_allclose(e, -0.1 * load.press_mm + 2 * e1, atol=1e-15)


def test_fit_recovers_gain_and_base():
    truth = SkinParams(l0_gain=0.6, l0_base=-0.08)
    prof = StepProfile(12.5)
    t, e = strain_history(prof, 40.0, params=truth)
    load = loading_history(truth, 40.0)
    sl = slice(load.slide_start, None)
    fitted = fit_l0(prof, e[sl], load.travel_mm[sl], params=P)
    assert fitted.l0_gain == pytest.approx(0.6, rel=1e-10)
    assert fitted.l0_base == pytest.approx(-0.08, rel=1e-10)


@pytest.mark.parametrize("speed", [1.0, 200.0])
def test_extreme_speeds_resolve_the_spikes(speed):
    t, e = strain_history(StepProfile(10.0), speed)
    assert np.all(np.isfinite(e))
    assert np.max(e) == pytest.approx(-np.min(e), rel=1e-3)
    assert np.max(e) > 0.9 * np.max(step_kernel(np.linspace(-1, 1, 4001), P)) * 0.01


@pytest.mark.parametrize("kw", [dict(e_mpa=(0.1, 0.2)), dict(e_mpa=(0.1, -1, 0.1)), dict(nu=0.5),
                                dict(prony_ratio=1.0), dict(thickness_mm=(0.4,)),
                                dict(radius_mm=0.0), dict(thickness_mm=(0.4, 5.0)),
                                dict(hold_s=-1.0), dict(corpuscle_depth_mm=2.5),
                                dict(press_mm=5.0), dict(l0_gain=float("nan")),
                                dict(thickness_mm=(0.4, -0.1))])
def test_bad_params_rejected(kw):
    with pytest.raises(ArgumentError):
        SkinParams(**kw)


@pytest.mark.parametrize("kw", [dict(height_um=float("inf")), dict(height_um=10.0, position_mm=float("nan")),
                                dict(height_um=10.0, edge_um=-1.0)])
def test_bad_profile_rejected(kw):
    with pytest.raises(ArgumentError):
        StepProfile(**kw)


@pytest.mark.parametrize("speed, dt, level", [(0.0, None, "l0"), (float("nan"), None, "l0"),
                                              (20.0, -1e-3, "l0"), (20.0, 1e-9, "l0"),
                                              (20.0, None, "l3")])
def test_bad_calls_rejected(speed, dt, level):
    with pytest.raises(ArgumentError):
        strain_history(StepProfile(10.0), speed, level=level, dt_s=dt)


def test_step_down_mirrors_step_up():
    _, up = strain_history(StepProfile(10.0), 20.0)
    _, down = strain_history(StepProfile(-10.0), 20.0)
    np.testing.assert_allclose(down, -up, atol=1e-15)


def test_sharp_profile_height():
    prof = StepProfile(10.0, position_mm=1.0, edge_um=0.0)
    np.testing.assert_allclose(prof.height_mm([0.5, 1.0, 1.5]), [0.0, 0.005, 0.01])
    ramp = StepProfile(10.0, position_mm=1.0, edge_um=100.0)
    np.testing.assert_allclose(ramp.height_mm([0.9, 0.975, 1.0, 1.1]), [0.0, 0.0025, 0.005, 0.01])


def test_exact_ramp_average_matches_quadrature_of_sharp_kernel():
    xi = np.linspace(-12, 12, 4001)
    nodes, weights = np.polynomial.legendre.leggauss(16)
    e_mm = 0.05
    ref = 0.5 * sum(w * step_kernel(xi - 0.5 * e_mm * x, P, 0.0) for x, w in zip(nodes, weights))
    np.testing.assert_allclose(step_kernel(xi, P, 50.0), ref, rtol=1e-6, atol=1e-9)


def test_surface_module_step_is_accepted():
    from feeler.models import surface
    t, e = strain_history(surface.step(5.0, 0.01), 20.0)
    _, ref = strain_history(StepProfile(10.0, 5.0, 50.0), 20.0)
    np.testing.assert_allclose(e, ref, rtol=1e-12)
    with pytest.raises(ArgumentError, match="exactly one step"):
        strain_history(surface.staircase(1.0, 1.0, 0.01, 3), 20.0)
    with pytest.raises(ArgumentError, match="StepProfile"):
        strain_history(10.0, 20.0)
