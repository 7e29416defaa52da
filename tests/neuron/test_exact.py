"""Hand-computed cases of the neuron core (DESIGN §4), exact to rounding."""
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from feeler.models.neuron import peak_pulse_density, peak_window_sum, pulse_density, window_sum


def test_ramp_rises_linearly_for_tau_then_plateaus():
    # ε = 0.1·t ⇒ ε̇ = 0.1 from the 2nd sample, x = a·0.1 = 0.2; u = x·min(t − t0, τ)
    t = np.arange(12) * 0.5
    z = pulse_density(0.1 * t, t, a=2.0, tau=2.0, h=0.0)
    expected = 0.2 * np.minimum(t, 2.0)
    np.testing.assert_allclose(z, expected, rtol=0, atol=1e-15)


def test_fractional_tau_counts_the_straddling_interval_by_its_fraction():
    # Δt = 0.5, τ = 1.25 = 2.5 samples ⇒ plateau at x·τ = 0.25 reached at t = 1.25 (3rd sample)
    t = np.arange(8) * 0.5
    u = window_sum(0.1 * t, t, tau=1.25)
    np.testing.assert_allclose(u, [0, 0.05, 0.1, 0.125, 0.125, 0.125, 0.125, 0.125], atol=1e-15)


def test_non_uniform_times_by_hand():
    t = np.array([0, 0.3, 1.0, 1.1, 2.5, 2.6, 4.0])
    eps = np.array([0, 1, 0, 2, 2, 5, 4.0])
    # |Δε| per interval: 1, 1, 2, 0, 3, 1. Window (t_k − 1, t_k]:
    # k=3: (0.1, 1.1] holds 2/3 of interval 1, all of 2 and 3 ⇒ 2/3 + 1 + 2
    # k=6: (3.0, 4.0] holds 1/1.4 of interval 6 ⇒ 1/1.4
    expected = [0, 1, 2, 1 + 2 + 2 / 3, 0, 3, 1 / 1.4]
    np.testing.assert_allclose(window_sum(eps, t, tau=1.0), expected, rtol=1e-14)


def test_threshold_and_gain():
    t = np.arange(6) * 1.0
    eps = np.array([0, 1, 1, 3, 3, 3.0])
    u1 = window_sum(eps, t, tau=2.0)             # [0, 1, 1, 2, 2, 0]
    np.testing.assert_allclose(u1, [0, 1, 1, 2, 2, 0])
    z = pulse_density(eps, t, a=3.0, tau=2.0, h=4.0)
    np.testing.assert_allclose(z, [0, 0, 0, 2, 2, 0])


def test_several_receptors_with_weights_sum_spatially():
    t = np.arange(5) * 1.0
    eps = np.array([[0, 1, 2, 3, 4.0],      # |Δε| = 1 each step
                    [0, 0, 2, 2, 2.0]])     # |Δε| = 0, 2, 0, 0
    w = np.array([0.5, 2.0])
    u = window_sum(eps, t, tau=2.0, weights=w)
    # per receptor windows of 2 s: r0 → [0,1,2,2,2], r1 → [0,0,2,2,0]
    np.testing.assert_allclose(u, 0.5 * np.array([0, 1, 2, 2, 2]) + 2.0 * np.array([0, 0, 2, 2, 0]))
    # leading batch axes are kept, the receptor axis is summed away
    batch = np.stack([eps, 2 * eps])
    np.testing.assert_allclose(window_sum(batch, t, tau=2.0, weights=w), np.stack([u, 2 * u]))


def test_exponential_kernel_against_closed_form():
    # constant receptor output x from t0 on: u(t) = x·τ·(1 − e^(−(t − t0)/τ)), exact for
    # any sampling because the output is piecewise constant
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.01, 0.2, size=200))
    x, tau = 0.7, 0.4
    eps = x * (t - t[0])
    u = window_sum(eps, t, tau=tau, kernel="exponential")
    np.testing.assert_allclose(u, x * tau * (1 - np.exp(-(t - t[0]) / tau)), rtol=1e-12, atol=1e-15)


def test_exponential_kernel_decays_after_the_input_stops():
    t = np.arange(0, 5.0, 0.25)
    eps = np.minimum(t, 1.0)   # rate 1 until t = 1, then constant
    u = window_sum(eps, t, tau=0.5, kernel="exponential")
    after = t > 1.0
    np.testing.assert_allclose(u[after], 0.5 * (1 - np.exp(-2.0)) * np.exp(-(t[after] - 1.0) / 0.5),
                               rtol=1e-12)


def test_fast_path_equals_the_peak_of_z_for_many_a_and_h():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.1, 0.9, size=300))
    eps = rng.normal(size=(4, 300)).cumsum(axis=1)
    peak_u1 = peak_window_sum(eps, t, tau=3.0)
    a = rng.uniform(0.1, 10, size=(50, 1))
    h = rng.uniform(0, 20, size=(50, 1))
    fast = peak_pulse_density(peak_u1, a, h)
    slow = np.stack([pulse_density(eps, t, a=ai, tau=3.0, h=hi).max(axis=-1)
                     for ai, hi in zip(a[:, 0], h[:, 0])])
    np.testing.assert_allclose(fast, slow, rtol=1e-12, atol=1e-12)


def test_u_is_linear_in_a():
    rng = np.random.default_rng(1)
    t = np.arange(100) * 0.5
    eps = rng.normal(size=100).cumsum()
    z1 = pulse_density(eps, t, a=1.0, tau=3.0, h=0.0)
    np.testing.assert_allclose(pulse_density(eps, t, a=7.5, tau=3.0, h=0.0), 7.5 * z1, rtol=1e-14)


@pytest.mark.parametrize("kernel", ["boxcar", "exponential"])
def test_empty_and_single_sample_records(kernel):
    assert pulse_density(np.empty(0), np.empty(0), a=1, tau=1, h=0, kernel=kernel).shape == (0,)
    np.testing.assert_array_equal(pulse_density([5.0], [0.0], a=1, tau=1, h=0, kernel=kernel), [0.0])
    assert peak_window_sum(np.empty((3, 0)), np.empty(0), tau=1.0).shape == (3,)


@pytest.mark.parametrize("tau", [0.004, 0.053, 0.1, 0.1234, 3.0, 25.0, 1e4])
@pytest.mark.parametrize("n", [5, 63, 64, 1001, 20000, 300_001])
def test_uniform_lanes_and_general_loop_agree(tau, n):
    """Uniform records take the pointer-free (strided or direct) loop, long ones cut across the
    threads; a stream of jittered times takes the general one. They compute the same u₁."""
    from feeler.models.neuron import FA1Stream
    rng = np.random.default_rng(n)
    t = np.arange(n) * 0.01
    eps = rng.normal(size=n).cumsum()
    stream = FA1Stream(a=1.0, tau=tau, h=0.0)
    stream.push_u1(np.array([-1.0, -0.5]), np.array([eps[0], eps[0]]))   # non-uniform start:
    general = stream.push_u1(t, eps)                  # the general loop from here on (flat start)
    np.testing.assert_allclose(window_sum(eps, t, tau=tau), general, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("where", [7, 150_000, 150_001, 299_999])
def test_long_record_off_the_grid_takes_the_general_loop(where):
    """One jittered step in a long record: the threads that checked t find it off the
    uniform grid and the record goes to the general loop — same u₁ as a stream of it."""
    from feeler.models.neuron import FA1Stream
    n = 300_001
    rng = np.random.default_rng(where)
    t = np.arange(n) * 0.01
    t[where] += 0.004
    eps = rng.normal(size=n).cumsum()
    stream = FA1Stream(a=1.0, tau=3.0, h=0.0)
    general = np.concatenate([stream.push_u1(t[:where], eps[:where]), stream.push_u1(t[where:], eps[where:])])
    np.testing.assert_allclose(window_sum(eps, t, tau=3.0), general, rtol=1e-10, atol=1e-12)


def test_each_cached_kernel_is_its_own_python_function():
    """numba's cache is keyed on the Python function: one function compiled twice (the
    parallel and the serial row loop) would load one build for both — the parallel loop
    silently ran serially once the cache was warm."""
    import numba
    from feeler.models.neuron import kernels, uniform
    seen = {}
    for mod in (kernels, uniform):
        for name, obj in vars(mod).items():
            if isinstance(obj, numba.core.registry.CPUDispatcher) and obj._cache.__class__.__name__ != "NullCache":
                key = (obj.py_func.__module__, obj.py_func.__qualname__)
                assert key not in seen, f"{name} and {seen[key]} share the cache of {key}"
                seen[key] = name
    assert {"_uniform_rows_par", "_uniform_rows_ser", "_boxcar_rows_par"} <= set(seen.values())


@pytest.mark.parametrize("shape", [(600_001,), (4, 150_001)])
@pytest.mark.parametrize("tau", [0.053, 3.0])
def test_long_loud_and_quiet_records_match_the_general_loop(shape, tau):
    """Alternating loud and quiet stretches (×10⁶) in a long record split across the
    threads and in parallel rows: blocks after each loud-to-quiet drop are recomputed
    compensated; every output matches the general (TwoSum) loop."""
    from feeler.models.neuron import FA1Stream
    n = shape[-1]
    rng = np.random.default_rng(n)
    t = np.arange(n) * 0.01
    loud = np.where((np.arange(n) // 20_000) % 2 == 0, 1.0, 1e-6)   # loud and quiet stretches
    eps = np.cumsum(rng.normal(size=shape) * loud, axis=-1)
    stream = FA1Stream(a=1.0, tau=tau, h=0.0)
    stream.push_u1(np.array([-1.0, -0.5]), np.repeat(eps[..., :1], 2, axis=-1))
    general = stream.push_u1(t, eps)                  # the general loop from here on
    np.testing.assert_allclose(window_sum(eps, t, tau=tau), general, rtol=1e-9, atol=1e-15)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), m=st.integers(0, 40), frac=st.sampled_from([0.0, 0.25, 0.5, 0.75]),
       n=st.integers(1, 5000), start=st.integers(0, 3000),
       pattern=st.sampled_from(["noise", "bursts", "flat runs", "huge range"]))
def test_uniform_kernel_is_within_1e10_of_the_exact_window_sum(seed, m, frac, n, start, pattern):
    """The uniform loops (direct sums for m < 8, the strided slide with its flagged-block
    recompute for m ≥ 8) against math.fsum of each window, for outputs from any start:
    relative error ≤ 1e-10 (the docstring's bound), exact zeros stay zero."""
    from feeler.models.neuron.uniform import boxcar_uniform
    assume(m + frac > 0)
    rng = np.random.default_rng(seed)
    inc = rng.normal(size=n)
    if pattern == "bursts":        # loud stretches between quiet ones (×10⁶)
        inc *= np.where((np.arange(n) // 300) % 2 == 0, 1.0, 1e-6)
    elif pattern == "flat runs":   # stretches with no change at all: window sums of exactly 0
        inc *= (np.arange(n) // 200) % 3 == 0
    elif pattern == "huge range":
        inc *= 10.0 ** rng.uniform(-8, 8, size=n)
    eps = np.cumsum(inc)
    start = min(start, n)
    final = np.zeros(1)
    out = boxcar_uniform(eps.reshape(1, 1, n), np.ones(1), 1.0, m + frac, final, start=start)[0]
    c = np.concatenate([[0.0], np.abs(np.diff(eps))])
    for k in range(start, n):
        exact = math.fsum(c[max(k - m + 1, 0):k + 1]) + (frac * c[k - m] if k - m >= 0 else 0.0)
        assert abs(out[k] - exact) <= 1e-10 * exact + 1e-300, (k, out[k], exact)
