"""Small statistics for the report's claims: bootstrap intervals over scans.

Scans of a plate are independent touches, so a statistic of several plates' samples gets
its 95 % interval by resampling each plate's scans with replacement (percentile
bootstrap, a seeded generator: the same run gives the same interval).
"""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np

__all__ = ["bootstrap_interval", "pc_interval", "N_BOOT"]

N_BOOT = 2000


def bootstrap_interval(stat: Callable[..., float], samples: Sequence[np.ndarray], *, n_boot: int = N_BOOT,
                       seed: int = 0, level: float = 0.95) -> tuple[float, float]:
    """Percentile interval of ``stat(*samples)`` with every sample resampled independently.

    Args:
        stat: a function of the samples (each ndarray[n_i]) returning a float.
        samples: one array per group (e.g. per plate), each with at least one value.
    Returns:
        (lo, hi) at ``level``; NaN where the statistic is not finite in most resamples.
    """
    rng = np.random.default_rng(seed)
    arrays = [np.asarray(s, float) for s in samples]
    values = np.empty(n_boot)
    for b in range(n_boot):
        values[b] = stat(*(a[rng.integers(0, a.size, a.size)] for a in arrays))
    ok = values[np.isfinite(values)]
    if ok.size < 0.9 * n_boot:
        return float("nan"), float("nan")
    tail = (1.0 - level) / 2
    lo, hi = np.quantile(ok, [tail, 1.0 - tail])
    return float(lo), float(hi)


def pc_interval(lower, higher) -> tuple[float, float]:
    """95 % interval of the proportion of pairs whose ``higher`` value is the larger
    (:func:`~feeler.datasets.proportion_correct`), by :func:`bootstrap_interval`, except
    when every pair is told apart (or none is): every resample then says the same, and the
    interval "1 [1, 1]" claimed a certainty 24 scans a plate cannot give (an outside review
    of the report). Its lower end is then the bound of n = the smaller plate's scans
    disjoint pairs all correct (:func:`~feeler.calib.neuron.discriminate.separation_bound`:
    0.86 at 24)."""
    from feeler.calib.neuron.discriminate import separation_bound
    from feeler.datasets import proportion_correct

    a, b = np.asarray(lower, float), np.asarray(higher, float)
    lo, hi = bootstrap_interval(proportion_correct, [a, b])
    bound = separation_bound(min(a.size, b.size))
    if lo >= 1.0:
        return min(bound, lo), hi
    if hi <= 0.0:
        return lo, max(1.0 - bound, hi)
    return lo, hi
