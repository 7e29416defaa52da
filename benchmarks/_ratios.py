"""Shared helpers of the benchmarks: a baseline timed in the same run, and the ratios."""
from __future__ import annotations

import time

__all__ = ["best_seconds", "record_ratio", "BaselineBetweenRounds", "RATIOS"]

RATIOS: list[tuple[str, float, str]] = []


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
    are sampled over the same stretch of the run, and ``best`` is the baseline's best.

    On this VM the speed of a memory-heavy call drifts over seconds (most likely other
    work on the host sharing its L3 and memory); a baseline timed only before the rounds
    can land in a different state than the rounds themselves."""

    def __init__(self, baseline, every: int):
        self.baseline, self.every = baseline, every
        self.calls = 0
        self.best = float("inf")

    def __call__(self) -> None:
        if self.calls % self.every == 0:
            self.best = min(self.best, best_seconds(self.baseline, repeat=1))
        self.calls += 1


def record_ratio(benchmark, name: str, ratio: float, goal: str) -> None:
    """Attach a ratio to the benchmark's JSON and to the closing summary."""
    benchmark.extra_info[name] = ratio
    RATIOS.append((f"{benchmark.name}: {name}", ratio, goal))
