"""Shared helpers of the benchmarks: a baseline timed in the same run, and the ratios."""
from __future__ import annotations

import time

__all__ = ["best_seconds", "record_ratio", "RATIOS"]

RATIOS: list[tuple[str, float, str]] = []


def best_seconds(func, repeat: int = 5) -> float:
    """Best wall time of ``func()`` over ``repeat`` calls (seconds)."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - t0)
    return best


def record_ratio(benchmark, name: str, ratio: float, goal: str) -> None:
    """Attach a ratio to the benchmark's JSON and to the closing summary."""
    benchmark.extra_info[name] = ratio
    RATIOS.append((f"{benchmark.name}: {name}", ratio, goal))
