"""Numerical behaviour at the extremes of τ, h, a, dtype and record length."""
import math

import numpy as np
import pytest

from feeler.models.neuron import FA1Stream, pulse_density, window_sum


def test_tau_below_one_sample_interval_gives_x_times_tau():
    t = np.arange(10) * 0.5
    eps = np.array([0, 1, 3, 2, 2, 6, 5, 5, 5, 9.0])
    u = window_sum(eps, t, tau=0.01)
    rate = np.abs(np.diff(eps, prepend=eps[0])) / 0.5
    np.testing.assert_allclose(u, rate * 0.01, rtol=1e-12)


def test_tau_longer_than_the_record_is_the_running_total_variation():
    rng = np.random.default_rng(2)
    t = np.cumsum(rng.uniform(0.1, 1, size=50))
    eps = rng.normal(size=50)
    u = window_sum(eps, t, tau=1e6)
    np.testing.assert_allclose(u, np.concatenate([[0], np.cumsum(np.abs(np.diff(eps)))]), rtol=1e-12)


def test_threshold_above_every_u_gives_zero():
    t = np.arange(100) * 0.1
    eps = np.sin(t)
    u = window_sum(eps, t, tau=1.0)
    assert not pulse_density(eps, t, a=1.0, tau=1.0, h=float(u.max()) + 1e-9).any()


@pytest.mark.parametrize("a", [1e-200, 1e-12, 1e12, 1e200])
def test_tiny_and_huge_gain_scale_exactly(a):
    t = np.arange(50) * 0.5
    eps = np.linspace(0, 1, 50) ** 2
    z = pulse_density(eps, t, a=a, tau=3.0, h=0.0)
    assert np.isfinite(z).all()
    np.testing.assert_allclose(z / a, window_sum(eps, t, tau=3.0), rtol=1e-14)


def test_float32_input_is_computed_in_float64():
    rng = np.random.default_rng(4)
    t = (np.arange(500) * 0.5).astype(np.float32)
    eps = rng.normal(size=500).cumsum().astype(np.float32)
    z32 = pulse_density(eps, t, a=1.0, tau=3.0, h=0.0)
    assert z32.dtype == np.float64
    np.testing.assert_array_equal(z32, pulse_density(eps.astype(np.float64), t.astype(np.float64),
                                                     a=1.0, tau=3.0, h=0.0))


def test_huge_and_tiny_tau_with_the_exponential_kernel_stay_finite():
    t = np.arange(100) * 1e-3
    eps = np.sin(50 * t)
    for tau in (1e-12, 1e-6, 1e6, 1e12):
        assert np.isfinite(window_sum(eps, t, tau=tau, kernel="exponential")).all()


def test_quiet_window_after_loud_ones_keeps_relative_precision():
    # loud increments (1e6) then quiet ones (1e-6): a plain sliding sum would keep the
    # loud rounding residue (~1e-10) and be wrong by ~100 % in the quiet part
    n = 4000
    t = np.arange(n) * 1.0
    rng = np.random.default_rng(5)
    steps = np.where(np.arange(n) < n // 2, 1e6, 1e-6) * rng.uniform(0.5, 1.5, n)
    eps = np.cumsum(steps * rng.choice([-1, 1], n))
    u = window_sum(eps, t, tau=10.0)
    c = np.abs(np.diff(eps, prepend=eps[0]))
    exact = np.array([math.fsum(c[max(k - 9, 0):k + 1]) for k in range(n)])
    np.testing.assert_allclose(u[n // 2 + 20:], exact[n // 2 + 20:], rtol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("sampling, m", [("uniform", 3), ("uniform", 300), ("jittered", 3)])
def test_long_stream_does_not_drift(sampling, m):
    """10⁸ samples streamed in 10⁶-sample chunks: u against an exact recomputation of
    the window sum (math.fsum) at quiet checkpoints after loud stretches. Uniform
    sampling runs the fast loops (direct sums for m = 3, the strided slide for m = 300),
    jittered sampling the general (pointer) loop. Times are multiples of 2⁻¹⁰ s, exact
    in float64, so the window's fractional edge is exact too."""
    n_total, chunk = 100_000_000, 1_000_000
    dt = 2.0 ** -10
    tau = (m + 0.5) * dt
    rng = np.random.default_rng(11)
    stream = FA1Stream(a=1.0, tau=tau, h=0.0)
    worst, last_eps = 0.0, 0.0
    for start in range(0, n_total, chunk):
        k = start + np.arange(chunk, dtype=np.float64)
        if sampling == "jittered":   # quarter-steps: still exact binary fractions
            k = k + rng.integers(0, 2, size=chunk) * 0.25
        t = k * dt
        inc = rng.normal(size=chunk)
        inc[-(m + 20):] *= 1e-6                # a quiet stretch at the checkpoint
        eps = last_eps + np.cumsum(inc)
        u = stream.push_u1(t, eps)
        c = np.abs(np.diff(eps[-(m + 5):]))    # increments of the last m + 4 intervals
        tt, T = t[-(m + 5):], t[-1] - tau      # window (T, t_k]
        parts = [ci if left >= T else ci * (right - T) / (right - left) if right > T else 0.0
                 for ci, left, right in zip(c, tt[:-1], tt[1:])]
        exact = math.fsum(parts)
        worst = max(worst, abs(u[-1] - exact) / exact)
        last_eps = eps[-1]
    assert worst < 1e-9, worst
