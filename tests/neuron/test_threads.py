"""Thread policy of the neuron core (models/neuron/threads.py): serial for little work
or a busy machine, the free cores otherwise; the same numbers on any thread count."""
from __future__ import annotations

import numba as nb
import numpy as np
import pytest

from feeler.errors import ArgumentError
from feeler.models.neuron import FA1Stream, pulse_density, threads
from feeler.models.neuron.threads import PARALLEL_MIN_SAMPLES, free_cpus, run_parallel, threads_for

BIG = 4 * PARALLEL_MIN_SAMPLES


@pytest.fixture
def loadavg(tmp_path, monkeypatch):
    """Point the policy at a fake /proc/loadavg; returns a writer of its running count."""
    path = tmp_path / "loadavg"
    monkeypatch.setattr(threads, "_LOADAVG", str(path))
    monkeypatch.setattr(threads, "_fd", [])
    monkeypatch.setattr(threads, "_affinity", lambda: 2)
    monkeypatch.delenv(threads.ENV, raising=False)

    def write(running: int) -> None:
        path.write_text(f"3.10 2.50 2.00 {running}/321 4567\n")
    return write


def test_little_work_or_one_row_runs_serially(loadavg):
    loadavg(1)
    assert threads_for(PARALLEL_MIN_SAMPLES - 1, 8) == 1
    assert threads_for(BIG, 1) == 1


def test_free_cores_are_counted_now(loadavg):
    loadavg(1)                       # only this thread runs: both cores free
    assert free_cpus() == 2 and threads_for(BIG, 8) == min(2, nb.get_num_threads())
    loadavg(2)                       # another task holds a core
    assert free_cpus() == 1 and threads_for(BIG, 8) == 1
    loadavg(9)                       # oversubscribed: still one thread, never zero
    assert free_cpus() == 1 and threads_for(BIG) == 1


def test_rows_cap_the_threads(loadavg, monkeypatch):
    monkeypatch.setattr(threads, "_affinity", lambda: 64)
    loadavg(1)
    assert threads_for(BIG, 2) == min(2, nb.get_num_threads())


def test_unreadable_loadavg_falls_back_to_the_load_average(loadavg, monkeypatch):
    monkeypatch.setattr(threads, "_LOADAVG", "/nonexistent/loadavg")
    monkeypatch.setattr(threads.os, "getloadavg", lambda: (5.0, 5.0, 5.0))
    assert free_cpus() == 1
    monkeypatch.setattr(threads.os, "getloadavg", lambda: (0.0, 0.0, 0.0))
    assert free_cpus() == 2


def test_pinned_count_ignores_the_load(loadavg, monkeypatch):
    loadavg(9)
    monkeypatch.setenv(threads.ENV, "2")
    assert threads_for(BIG, 8) == min(2, nb.get_num_threads())
    monkeypatch.setenv(threads.ENV, "auto")
    assert threads_for(BIG, 8) == 1


@pytest.mark.parametrize("bad", ["0", "-1", "two", "1.5"])
def test_bad_pinned_count_is_a_one_line_error(monkeypatch, bad):
    monkeypatch.setenv(threads.ENV, bad)
    with pytest.raises(ArgumentError, match=rf"argument {threads.ENV}='?{bad}'?: a positive integer"):
        threads_for(BIG, 8)


def test_run_parallel_restores_the_thread_count():
    before = nb.get_num_threads()
    seen = run_parallel(lambda: nb.get_num_threads(), 1)
    assert seen == 1 and nb.get_num_threads() == before


@pytest.mark.skipif(nb.config.NUMBA_NUM_THREADS < 2, reason="needs two numba threads")
@pytest.mark.parametrize("shape, uniform", [((1, 300_001), True), ((8, 20_000), True), ((8, 20_000), False)])
def test_same_numbers_on_one_thread_and_on_two(monkeypatch, shape, uniform):
    """Rows in parallel are bit-identical; a record cut into pieces starts each piece
    from exact window sums (equal to 1e-10, the uniform loops' bound)."""
    rng = np.random.default_rng(3)
    eps = rng.normal(size=shape).cumsum(axis=-1)
    t = np.arange(shape[-1]) * 1e-3
    if not uniform:
        t = t + rng.uniform(0, 2e-4, t.size)
    out = {}
    for n in ("1", "2"):
        monkeypatch.setenv(threads.ENV, n)
        out[n] = pulse_density(eps, t, a=2.0, tau=0.3, h=0.1)
    if shape[0] == 1:
        np.testing.assert_allclose(out["2"], out["1"], rtol=1e-10, atol=1e-10 * np.abs(out["1"]).max())
    else:
        np.testing.assert_array_equal(out["2"], out["1"])


@pytest.mark.skipif(nb.config.NUMBA_NUM_THREADS < 2, reason="needs two numba threads")
def test_long_record_checked_inside_two_threads_names_the_bad_time(monkeypatch):
    monkeypatch.setenv(threads.ENV, "2")
    t = np.arange(300_001) * 1e-3
    t[200_000] = t[199_999]
    with pytest.raises(ArgumentError, match=r"argument t=.* at index 200000\b"):
        pulse_density(np.arange(t.size) * 0.1, t, a=1.0, tau=0.3, h=0.0)


def test_stream_on_two_threads_equals_batch(monkeypatch):
    monkeypatch.setenv(threads.ENV, "2")
    rng = np.random.default_rng(4)
    x = rng.normal(size=(16, 3 * 8192)).cumsum(axis=1)
    t = np.arange(x.shape[1]) * 1e-3
    s = FA1Stream(a=1.0, tau=0.3, h=0.0)
    got = np.concatenate([s.push(t[i:i + 8192], x[:, i:i + 8192]) for i in range(0, x.shape[1], 8192)], axis=1)
    np.testing.assert_allclose(got, pulse_density(x, t, a=1.0, tau=0.3, h=0.0), rtol=1e-10, atol=1e-12)
