"""Shared helpers of the benchmarks: a baseline timed in the same run, and the ratios.

Two families:

- best-of (``best_seconds``, ``BaselineBetweenRounds``, ``record_ratio``): the fastest
  call, what the code can do on a quiet machine;
- medians (``seconds_of``, ``Timed``, ``record_median_ratio``, ``busy_loops``): what a
  user gets. A figure is the ratio of the baseline's median to the call's median, with
  its spread from the call's 10th–90th percentiles against the baseline's median, and
  the best-of ratio beside it as an extra column; measured idle and with two busy-loop
  processes competing for the cores (:func:`busy_loops`, the in-run equivalent of
  ``.ci/with-load -n 2``), each against a baseline timed under the same load.
"""
from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import time
from dataclasses import dataclass

import numpy as np

__all__ = ["best_seconds", "record_ratio", "BaselineBetweenRounds", "RATIOS", "seconds_of", "Timed",
           "record_median_ratio", "busy_loops", "LOADS", "FULL", "full_only"]

# FEELER_FULL=1: heavy validations at full size, and the benchmarks only it runs (full_only)
FULL = os.environ.get("FEELER_FULL") == "1"


def full_only(what: str):
    """A mark that skips a benchmark unless ``FEELER_FULL=1``; ``what`` says what it runs
    and how long it takes (the skip reason)."""
    import pytest

    return pytest.mark.skipif(not FULL, reason=f"{what}: FEELER_FULL=1")


# (name, ratio, goal) from record_ratio; (name, ratio, goal, extra columns) from record_median_ratio
RATIOS: list[tuple] = []
# the loads every median figure is measured under: label -> busy-loop processes started
# in the run; under `make bench-load` the whole run is already loaded (.ci/with-load)
LOADS = ({"2 busy loops (with-load)": 0} if os.environ.get("FEELER_BENCH_UNDER_LOAD")
         else {"idle": 0, "2 busy loops": 2})


def best_seconds(func, repeat: int = 5) -> float:
    """Best wall time of ``func()`` over ``repeat`` calls (seconds)."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - t0)
    return best


class BaselineBetweenRounds:
    """A ``setup`` hook for ``benchmark.pedantic`` (untimed) that times ``baseline`` once
    every ``every`` rounds, the first included: the baseline and the benchmarked call
    are sampled over the same stretch of the run, and ``best`` is the baseline's best
    (``times`` keeps every baseline time, for medians).

    On this VM the speed of a memory-heavy call drifts over seconds (most likely other
    work on the host sharing its L3 and memory); a baseline timed only before the rounds
    can land in a different state than the rounds themselves."""

    def __init__(self, baseline, every: int):
        self.baseline, self.every = baseline, every
        self.calls = 0
        self.best = float("inf")
        self.times: list[float] = []

    def __call__(self) -> None:
        if self.calls % self.every == 0:
            t = best_seconds(self.baseline, repeat=1)
            self.times.append(t)
            self.best = min(self.best, t)
        self.calls += 1


def record_ratio(benchmark, name: str, ratio: float, goal: str) -> None:
    """Attach a ratio to the benchmark's JSON and to the closing summary."""
    benchmark.extra_info[name] = ratio
    RATIOS.append((f"{benchmark.name}: {name}", ratio, goal))


def seconds_of(func, rounds: int, *, warmup: int = 1) -> np.ndarray:
    """Wall times of ``rounds`` calls of ``func()`` after ``warmup`` untimed ones (s)."""
    for _ in range(warmup):
        func()
    out = np.empty(rounds)
    for i in range(rounds):
        t0 = time.perf_counter()
        func()
        out[i] = time.perf_counter() - t0
    return out


@dataclass(frozen=True)
class Timed:
    """Wall times of one call (``call``) and of its baseline (``base``), seconds, taken
    over the same stretch of a run (interleaved: :meth:`interleaved`)."""
    call: np.ndarray
    base: np.ndarray

    @classmethod
    def interleaved(cls, func, baseline, *, rounds: int, base_every: int = 1, warmup: int = 2) -> "Timed":
        """``rounds`` timed calls of ``func`` with ``baseline`` timed beside every
        ``base_every``-th one (both warmed up ``warmup`` times first). With
        ``base_every=1`` the two alternate which goes first: on a loaded machine the
        second of two back-to-back calls is preempted more often (its process's time
        slice is spent), which would bias a fixed order."""
        for _ in range(warmup):
            baseline()
            func()
        call, base = np.empty(rounds), []
        for i in range(rounds):
            with_base = i % base_every == 0
            if with_base and (base_every > 1 or i % 2 == 0):
                base.append(seconds_of(baseline, 1, warmup=0)[0])
                with_base = False
            call[i] = seconds_of(func, 1, warmup=0)[0]
            if with_base:
                base.append(seconds_of(baseline, 1, warmup=0)[0])
        return cls(call=call, base=np.asarray(base))

    @staticmethod
    def rotated(funcs: dict, rounds: int) -> dict:
        """Wall times (s) of each of ``funcs`` (name → callable) over ``rounds`` rounds,
        the order rotating every round so that each takes every slot equally often."""
        names = list(funcs)
        out = {k: np.empty(rounds) for k in names}
        for i in range(rounds):
            for j in range(len(names)):
                k = names[(i + j) % len(names)]
                out[k][i] = seconds_of(funcs[k], 1, warmup=0)[0]
        return out


def record_median_ratio(benchmark, name: str, timed: Timed, goal: str, *, load: str = "idle",
                        invert: bool = False) -> float:
    """Record ``median(base) / median(call)`` (``invert``: ``median(call) / median(base)``)
    with its spread (the call's p10 and p90 against the baseline's median) and the
    best-of ratio, under ``load``; returns the median ratio.

    Goes to the benchmark's ``extra_info`` (``<name> [<load>]: median|p10|p90|best``,
    plus the call's and the baseline's median seconds) and to the closing summary."""
    b, c = np.median(timed.base), timed.call
    q10, q50, q90 = np.percentile(c, [10, 50, 90])

    def r(call_s, base_s=b):
        return call_s / base_s if invert else base_s / call_s

    # the spread is ordered low → high ratio whichever way the ratio runs
    lo, hi = sorted((r(q90), r(q10)))
    row = {"median": r(q50), "p10": lo, "p90": hi, "best": r(c.min(), timed.base.min())}
    key = f"{name} [{load}]"
    for stat, value in row.items():
        benchmark.extra_info[f"{key}: {stat}"] = float(value)
    benchmark.extra_info[f"{key}: call median s"] = float(q50)
    benchmark.extra_info[f"{key}: baseline median s"] = float(b)
    RATIOS.append((f"{benchmark.name}: {key}", float(row["median"]), goal,
                   {"p10": float(lo), "p90": float(hi), "best": float(row["best"]), "load": load,
                    "rounds": int(c.size)}))
    return float(row["median"])


@contextlib.contextmanager
def busy_loops(n: int = 2):
    """``n`` busy-loop processes competing for the cores while the block runs; started
    here and stopped by PID when it ends (as ``.ci/with-load -n N``). n = 0: no load."""
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    try:
        time.sleep(0.2 if n else 0.0)      # let the scheduler place them
        yield procs
    finally:
        for p in procs:
            p.kill()
        for p in procs:
            p.wait()
