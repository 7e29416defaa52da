"""Neuron throughput as ratios to baselines measured in the same run (issue 2 §7, issue 18).

Every figure is a median with its spread (``_ratios.record_median_ratio``), idle and
with two busy-loop processes competing for the cores, each against its baseline timed
interleaved with it under the same load; the best-of ratio is an extra column:

- one channel of 10⁷ samples: throughput / that of a plain array copy (goal ≥ 0.25);
- 256 channels of 10⁷ samples, streamed in chunks: / copying the same chunks (goal ≥ 0.5);
- against direct convolution (``np.convolve`` with the boxcar) at τ/Δt = 300 (goal ≥ 50×),
  read at 5·10⁵ samples, the longest record whose arrays stay in this VM's cache (see
  :func:`test_vs_direct_convolution_at_300_samples`); the other lengths are reported;
- no thread cliff (:func:`test_no_thread_cliff`): every parallel path's median with the
  thread policy of models/neuron/threads.py, against the same call pinned to one thread
  (goal ≤ 2 under load), and pinned to two threads (the cliff the policy avoids).
"""
import os

import numba as nb
import numpy as np
import pytest

from _ratios import (LOADS, BaselineBetweenRounds, Timed, best_seconds, busy_loops, record_median_ratio,
                     record_ratio)
from feeler.models.neuron import FA1Stream, pulse_density, threads

N = 10_000_000
DT = 1e-3


@pytest.fixture(scope="module")
def one_channel():
    rng = np.random.default_rng(0)
    t = np.arange(N) * DT
    eps = rng.normal(size=N).cumsum()
    pulse_density(eps[:100], t[:100], a=1, tau=0.3, h=0)  # compile outside the timing
    return t, eps


def test_one_channel_vs_copy(benchmark, one_channel):
    t, eps = one_channel
    copy = BaselineBetweenRounds(lambda: eps.copy(), every=1)
    # the first calls of a process map fresh pages for the 80 MB output: warm up first
    benchmark.pedantic(pulse_density, args=(eps, t), kwargs=dict(a=1.0, tau=0.3, h=0.0), setup=copy,
                       rounds=10, warmup_rounds=2, iterations=1)
    record_ratio(benchmark, "throughput / copy", copy.best / benchmark.stats["min"], ">= 0.25")
    for load, n in LOADS.items():
        with busy_loops(n):
            timed = (Timed(call=np.asarray(benchmark.stats.stats.data), base=np.asarray(copy.times[2:]))
                     if n == 0 else
                     Timed.interleaved(lambda: pulse_density(eps, t, a=1.0, tau=0.3, h=0.0), eps.copy, rounds=10))
        record_median_ratio(benchmark, "throughput / copy", timed, ">= 0.25", load=load)


def test_256_channels_streamed_vs_copy(benchmark):
    rows, chunk = 256, 1 << 15
    rng = np.random.default_rng(1)
    block = rng.normal(size=(rows, chunk)).cumsum(axis=1)
    n_chunks = N // chunk

    def run(chunks=n_chunks):
        stream = FA1Stream(a=1.0, tau=0.3, h=0.0)
        for i in range(chunks):
            stream.push((i * chunk + np.arange(chunk)) * DT, block)

    def copies(chunks=n_chunks):
        for _ in range(chunks):
            block.copy()

    FA1Stream(a=1.0, tau=0.3, h=0.0).push(np.arange(chunk) * DT, block)  # compile
    # three ~3 s rounds, each after a copy of the same chunks: one round alone moved
    # between 0.475 and 0.765 of the copy in one session with the same code
    copy = BaselineBetweenRounds(copies, every=1)
    benchmark.pedantic(run, setup=copy, rounds=3, iterations=1)
    record_ratio(benchmark, "throughput / copy (256 ch)", copy.best / benchmark.stats["min"], ">= 0.5")
    for load, n in LOADS.items():
        with busy_loops(n):
            # loaded: a tenth of the stream per round (each round takes seconds on a busy machine)
            timed = (Timed(call=np.asarray(benchmark.stats.stats.data), base=np.asarray(copy.times))
                     if n == 0 else Timed.interleaved(lambda: run(n_chunks // 10), lambda: copies(n_chunks // 10),
                                                      rounds=3, warmup=0))
        record_median_ratio(benchmark, "throughput / copy (256 ch)", timed, ">= 0.5", load=load)


@nb.njit(parallel=True)
def _sum_into(x, t, out):
    """out = x + t on all cores: pulse_density's memory traffic (read strain and times,
    write the output) without its arithmetic."""
    for i in nb.prange(x.shape[0]):
        out[i] = x[i] + t[i]


# the length the ≥ 50× goal is read at (see the test's docstring)
GOAL_N = 500_000


@pytest.mark.parametrize("n", [GOAL_N, 1_000_000, 10_000, 100_000, 200_000, 10_000_000])
def test_vs_direct_convolution_at_300_samples(benchmark, n):
    """np.convolve does 300 multiply-adds per sample and is compute-bound at every
    length; pulse_density does a few operations per sample, so once its arrays (strain,
    times and output: 24 bytes per sample, plus the previous output pytest-benchmark
    keeps alive) leave the cache it runs at the speed of memory instead. On this VM
    (32 MB of L3 by lscpu, most likely shared with the host's other work: the swings at
    10⁶ look like it, though the VM gives no direct view):

    - ≤ 5·10⁵ samples: the arrays stay cached and the ratio is the algorithm's; the goal
      is read at 5·10⁵ (16 MB with the kept output);
    - 10⁶ samples (32 MB): at the edge, the ratio moves from run to run (31–73× over
      28 runs of the same code);
    - 10⁷ samples (240 MB): bound by memory bandwidth; "np.convolve / (out = strain + t)"
      is the ratio a kernel doing no arithmetic at all would reach, measured here;
    - 10⁴ samples: the ~9 µs of argument checks per call dominate.

    The median figures: idle, the rounds above (np.convolve before every 30th call);
    loaded, np.convolve before every 10th call (every call at 10⁷, 3 rounds).
    """
    m = 300
    rng = np.random.default_rng(2)
    t = np.arange(n) * DT
    eps = rng.normal(size=n).cumsum()
    tau = m * DT

    def convolve():
        rate = np.abs(np.diff(eps, prepend=eps[0])) / DT
        return np.convolve(rate, np.ones(m) * DT)[:n]

    # same numbers (τ an exact multiple of Δt: no fractional edge)
    np.testing.assert_allclose(pulse_density(eps, t, a=1.0, tau=tau, h=0.0)[m:], convolve()[m:],
                               rtol=1e-6)
    # np.convolve is timed between the rounds (untimed for the benchmark), so both sides
    # are sampled over the same stretch of the run. A sub-millisecond call: after a pause
    # (np.convolve, a busy wait or a sleep alike) this VM's memory system needs ~10 calls
    # to reach its steady speed, so each baseline call is followed by 30 rounds, and the
    # best round is the steady throughput.
    long = n > 1_000_000
    conv = BaselineBetweenRounds(convolve, every=1 if long else 30)
    benchmark.pedantic(pulse_density, args=(eps, t), kwargs=dict(a=1.0, tau=tau, h=0.0), setup=conv,
                       rounds=5 if long else 300, warmup_rounds=2 if long else 10, iterations=1)
    goal = ">= 50" if n == GOAL_N else "informational"
    record_ratio(benchmark, "speed-up over np.convolve", conv.best / benchmark.stats["min"], goal)
    for load, k in LOADS.items():
        with busy_loops(k):
            timed = (Timed(call=np.asarray(benchmark.stats.stats.data), base=np.asarray(conv.times))
                     if k == 0 else
                     Timed.interleaved(lambda: pulse_density(eps, t, a=1.0, tau=tau, h=0.0), convolve,
                                       rounds=3 if long else 100, base_every=1 if long else 10))
        record_median_ratio(benchmark, "speed-up over np.convolve", timed, goal, load=load)
    if n in (GOAL_N, 1_000_000, 10_000_000):
        _sum_into(eps, t, np.empty(n))
        floor = best_seconds(lambda: _sum_into(eps, t, np.empty(n)), repeat=5 if long else 100)
        record_ratio(benchmark, "time / (out = strain + t, all cores)", benchmark.stats["min"] / floor,
                     "informational")
        if long:
            record_ratio(benchmark, "np.convolve / (out = strain + t): memory bound", conv.best / floor,
                         "informational")


def _case(kind: str, rows: int, n: int):
    """A call of one parallel path of the neuron core, and its rounds."""
    rng = np.random.default_rng(5)
    x = rng.normal(size=(rows, n)).cumsum(axis=1)
    t = np.arange(n) * DT
    rounds = int(np.clip(2e7 / (rows * n), 15, 200))
    if kind == "uniform":
        return (lambda: pulse_density(x if rows > 1 else x[0], t, a=1.0, tau=0.3, h=0.0)), rounds
    if kind == "jittered":          # the general loop (times off a uniform grid)
        tj = t + rng.uniform(0, 2e-4, n)
        return (lambda: pulse_density(x, tj, a=1.0, tau=0.3, h=0.0)), max(15, rounds // 4)
    if kind == "exponential":
        return (lambda: pulse_density(x, t, a=1.0, tau=0.3, h=0.0, kernel="exponential")), 15
    chunk = 4096                     # "stream": chunks of a live stream, as the decoder pushes them

    def stream():
        s = FA1Stream(a=1.0, tau=0.3, h=0.0)
        for i in range(0, n, chunk):
            s.push(t[i:i + chunk], x[:, i:i + chunk])
    return stream, rounds


@pytest.mark.parametrize("kind, rows, n", [("uniform", 1, 10_000), ("uniform", 1, 100_000),
                                           ("uniform", 1, 500_000), ("uniform", 1, 2_000_000),
                                           ("uniform", 8, 20_000), ("uniform", 16, 200_000),
                                           ("jittered", 8, 20_000), ("exponential", 16, 100_000),
                                           ("stream", 16, 81_920)])
def test_no_thread_cliff(benchmark, kind, rows, n):
    """Median of each parallel path under the thread policy (threads by the cores free
    per call) against the same call on one thread, interleaved, idle and with two busy
    loops: goal ≤ 2 under load (issue 18 §3, issue 13 §6). Two threads pinned shows the
    cliff without the policy (informational)."""
    call, rounds = _case(kind, rows, n)

    def pinned(k):
        def run():
            before = os.environ.get(threads.ENV)
            os.environ[threads.ENV] = str(k)
            try:
                call()
            finally:
                if before is None:
                    del os.environ[threads.ENV]
                else:
                    os.environ[threads.ENV] = before
        return run

    one, two = pinned(1), pinned(2)
    call(), one(), two()                                  # compile every path outside the timing
    benchmark.pedantic(call, rounds=5, iterations=1)
    for load, k in LOADS.items():
        with busy_loops(k):
            t = Timed.rotated({"auto": call, "one": one, "two": two}, rounds)
        goal = "<= 2" if k or load != "idle" else "informational"
        record_median_ratio(benchmark, "time / one thread", Timed(call=t["auto"], base=t["one"]), goal,
                            load=load, invert=True)
        record_median_ratio(benchmark, "two threads pinned / one thread", Timed(call=t["two"], base=t["one"]),
                            "informational", load=load, invert=True)
