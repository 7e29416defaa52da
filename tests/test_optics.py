"""The optical element model: area law, its exact inverse, the `areas` fidelity, rendering."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feeler.errors import ArgumentError
from feeler.models.optics import (CameraParams, OpticsParams, areas_from_force,
                                  displacement_from_force, force_from_areas,
                                  force_from_displacement, grid_layout, measure_areas,
                                  observe_areas, render_frames)

P = OpticsParams()
finite = dict(allow_nan=False, allow_infinity=False)
forces = st.tuples(st.floats(-0.3, 0.3, **finite), st.floats(0.0, 3.0, **finite),
                   st.floats(-0.3, 0.3, **finite))


def test_area_law_exact_cases():
    # F_y = 1 N spreads 800 px² over four feelers; F_x = 1 N moves 400 px² from −x to +x
    np.testing.assert_allclose(areas_from_force([0.0, 1.0, 0.0], P), [350.0] * 4)
    np.testing.assert_allclose(areas_from_force([1.0, 0.0, 0.0], P), [250.0, 250.0, 50.0, 50.0])
    np.testing.assert_allclose(areas_from_force([0.0, 0.0, 1.0], P), [250.0, 50.0, 250.0, 50.0])
    np.testing.assert_allclose(areas_from_force([0.0, 0.0, 0.0], P), [150.0] * 4)
    # sum law and difference laws read back from hand-made areas
    np.testing.assert_allclose(force_from_areas([200.0, 200.0, 200.0, 200.0], P), [0.0, 0.25, 0.0])
    np.testing.assert_allclose(force_from_areas([190.0, 170.0, 150.0, 130.0], P), [0.2, 0.05, 0.1])


@settings(max_examples=200, deadline=None)
@given(forces)
def test_force_from_areas_inverts_areas_from_force(f):
    back = force_from_areas(areas_from_force(np.array(f), P), P)
    np.testing.assert_allclose(back, f, rtol=0, atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(forces, st.floats(-50.0, 50.0, **finite))
def test_twist_combination_never_reaches_the_force(f, twist):
    areas = areas_from_force(np.array(f), P) + twist * np.array([1.0, -1.0, -1.0, 1.0])
    np.testing.assert_allclose(force_from_areas(areas, P), f, rtol=0, atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(st.tuples(*[st.floats(-2.0, 2.0, **finite)] * 3))
def test_displacement_force_round_trip(u):
    f = force_from_displacement(np.array(u), P.c_matrix)
    np.testing.assert_allclose(P.c_matrix @ f, u, atol=1e-12)
    np.testing.assert_allclose(displacement_from_force(f, P.c_matrix), u, atol=1e-12)


def test_batched_shapes_broadcast():
    f = np.zeros((2, 5, 3))
    f[..., 1] = 0.5
    assert areas_from_force(f, P).shape == (2, 5, 4)
    assert force_from_displacement(np.zeros((2, 5, 3)), P.c_matrix).shape == (2, 5, 3)


def test_force_outside_range_and_bad_shapes():
    with pytest.raises(ArgumentError, match="measuring range"):
        areas_from_force([0.0, -1.0, 0.0], P)
    with pytest.raises(ArgumentError, match=r"shape \(\.\.\., 3\)"):
        areas_from_force([1.0, 2.0], P)
    with pytest.raises(ArgumentError, match=r"shape \(\.\.\., 4\)"):
        force_from_areas(np.ones((3, 3)), P)


@pytest.mark.parametrize("kwargs, match", [
    (dict(c_mm_per_n=((1.0, 0.0), (0.0, 1.0))), "3×3"),
    (dict(c_mm_per_n=((1.0, 0, 0), (0, np.nan, 0), (0, 0, 1.0))), "3×3"),
    (dict(c_mm_per_n=((1.0, 2.0, 0), (2.0, 4.0, 0), (0, 0, 1.0))), "invertible"),
    (dict(gain_y_px2_per_n=0.0), "> 0"),
    (dict(rest_area_px2=-1.0), "> 0"),
    (dict(area_sd_px2=-0.1), "≥ 0"),
    (dict(area_step_px2=np.inf), "≥ 0"),
])
def test_optics_params_validation(kwargs, match):
    with pytest.raises(ArgumentError, match=match):
        OpticsParams(**kwargs)


def test_observe_areas_without_noise_is_exact():
    exact = OpticsParams(area_sd_px2=0.0, area_step_px2=0.0)
    u = np.zeros((3, 7, 3))
    u[..., 1] = np.linspace(0.1, 0.9, 7)
    u[..., 0] = 0.05
    out = observe_areas(u, params=exact, rng=np.random.default_rng(0))
    assert out.shape == u.shape
    np.testing.assert_allclose(out, u, atol=1e-12)


@pytest.mark.parametrize("sd, step", [(0.25, 0.0), (1.0, 1.0)])
def test_observe_areas_noise_matches_propagated_covariance(sd, step):
    # cov U = C K Σ_A Kᵀ Cᵀ with K = ∂F/∂A and Σ_A = (σ² + step²/12) I (the quantisation
    # error is uniform and independent when σ ≥ step — Sheppard; exact when step = 0)
    params = OpticsParams(area_sd_px2=sd, area_step_px2=step)
    rng = np.random.default_rng(7)
    u = np.tile([0.02, 0.4, -0.03], (40000, 1))[None]
    err = (observe_areas(u, params=params, rng=rng) - u)[0]
    k = (force_from_areas(np.eye(4), P) - force_from_areas(np.zeros(4), P)).T  # (3, 4)
    cov = P.c_matrix @ k @ k.T @ P.c_matrix.T * (sd ** 2 + step ** 2 / 12)
    np.testing.assert_allclose(err.std(axis=0), np.sqrt(np.diag(cov)), rtol=0.03)
    assert np.all(np.abs(err.mean(axis=0)) < 4 * np.sqrt(np.diag(cov) / 40000))


def test_observe_areas_bad_input():
    rng = np.random.default_rng(0)
    with pytest.raises(ArgumentError, match="n_time, 3"):
        observe_areas(np.zeros(3), params=P, rng=rng)
    with pytest.raises(ArgumentError, match="finite"):
        observe_areas(np.full((2, 3), np.nan), params=P, rng=rng)


def test_measured_areas_are_quantised_and_non_negative():
    got = measure_areas(np.array([0.2, 10.0, 100.4, 1000.0]), OpticsParams(area_sd_px2=0.0),
                        np.random.default_rng(0))
    np.testing.assert_array_equal(got, [0.0, 10.0, 100.0, 1000.0])
    noisy = measure_areas(np.zeros(1000), P, np.random.default_rng(1))
    assert noisy.min() == 0.0 and noisy.max() > 0.0
