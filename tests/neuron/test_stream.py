"""Streaming equals batch under any chunking (property tests)."""
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from feeler.models.neuron import FA1Stream, pulse_density


def _record(seed, n, uniform, channels):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.1 if uniform else np.cumsum(rng.uniform(0.01, 0.3, size=n))
    eps = rng.normal(size=(*channels, n)).cumsum(axis=-1)
    return t, eps


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(1, 120), uniform=st.booleans(),
       tau=st.floats(0.005, 20.0), kernel=st.sampled_from(["boxcar", "exponential"]),
       cuts=st.lists(st.integers(0, 120), max_size=8), weighted=st.booleans(),
       h=st.floats(0, 2))
def test_any_chunking_gives_the_batch_result(seed, n, uniform, tau, kernel, cuts, weighted, h):
    t, eps = _record(seed, n, uniform, (2, 3) if weighted else (2,))
    w = np.array([1.0, 0.5, 2.0]) if weighted else None
    batch = pulse_density(eps, t, a=1.3, tau=tau, h=h, weights=w, kernel=kernel)
    stream = FA1Stream(a=1.3, tau=tau, h=h, weights=w, kernel=kernel)
    edges = [0, *sorted(c % (n + 1) for c in cuts), n]
    parts = [stream.push(t[i:j], eps[..., i:j]) for i, j in zip(edges[:-1], edges[1:])]
    np.testing.assert_allclose(np.concatenate(parts, axis=-1), batch, rtol=1e-10, atol=1e-10)


def test_one_sample_at_a_time_long_window():
    t, eps = _record(7, 400, False, ())
    batch = pulse_density(eps, t, a=1.0, tau=5.0, h=0.0)
    s = FA1Stream(a=1.0, tau=5.0, h=0.0)
    one = np.concatenate([s.push(t[k:k + 1], eps[k:k + 1]) for k in range(400)])
    np.testing.assert_allclose(one, batch, rtol=1e-12, atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), tau=st.floats(0.01, 3.0), switch=st.integers(1, 300),
       cuts=st.lists(st.integers(1, 400), min_size=1, max_size=6))
def test_uniform_stream_handing_over_to_the_general_loop(seed, tau, switch, cuts):
    """Uniform chunks run the fast loops; a chunk that breaks the sampling hands the
    stream over to the general loop (history replayed). Either way: the batch result."""
    rng = np.random.default_rng(seed)
    n = 400
    t = np.arange(n) * 0.05
    t[switch:] += 0.013                      # one longer interval: no longer uniform
    eps = rng.normal(size=n).cumsum()
    batch = pulse_density(eps, t, a=1.0, tau=tau, h=0.0)
    stream = FA1Stream(a=1.0, tau=tau, h=0.0)
    edges = [0, *sorted(set(cuts)), n]
    parts = [stream.push(t[i:j], eps[i:j]) for i, j in zip(edges[:-1], edges[1:]) if j > i]
    np.testing.assert_allclose(np.concatenate(parts), batch, rtol=1e-10, atol=1e-10)
