"""Simulation-based calibration (Talts et al. 2018) for any model.

For each of ``n_datasets`` seeds: ``simulate(rng) -> (truth, data)`` draws parameters
from the prior and data from the model; ``fit(data, rng) -> draws`` returns posterior
draws (``dict[name] -> ndarray[any]``, flattened; independent or thinned). The rank of
the truth among ``n_draws`` draws is uniform on 0..n_draws when the fit is exact. Two
uniformity tests per parameter:

- chi-square on ``bins`` equal groups of rank values (p-value);
- the simultaneous ECDF band (Säilynoja, Bürkner & Vehtari 2022): the observed statistic
  is the smallest two-sided binomial tail probability of the rank ECDF over evaluation
  points; its null distribution is simulated with uniform ranks (p-value = fraction of
  simulated statistics at least as extreme); the 1 − α band is returned too.

Datasets fan out through :func:`feeler.calib.runner.map_seeds` (serial, LocalCluster or
a ``tcp://`` scheduler) with identical results for the same seeds.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Callable, Mapping

import numpy as np
from scipy import stats

from feeler.calib.runner import map_seeds
from feeler.errors import ArgumentError

__all__ = ["SBCResult", "run_sbc", "ranks_of", "chi2_uniformity", "ecdf_uniformity"]


@dataclass(frozen=True)
class SBCResult:
    """Ranks and uniformity p-values.

    Attributes:
        names (tuple[str, ...]): parameter names.
        ranks (ndarray[n_datasets, n_params]): ranks in 0..n_draws.
        n_draws (int): posterior draws per dataset used for the ranks.
        chi2_p, ecdf_p (ndarray[n_params]): p-values of the two uniformity tests.
    """
    names: tuple
    ranks: np.ndarray
    n_draws: int
    chi2_p: np.ndarray
    ecdf_p: np.ndarray

    def failed(self, alpha: float = 0.01) -> list[str]:
        """Parameters whose ranks are non-uniform at level ``alpha`` (Bonferroni over
        parameters and the two tests)."""
        level = alpha / (2 * len(self.names))
        return [n for n, a, b in zip(self.names, self.chi2_p, self.ecdf_p) if min(a, b) < level]

    def table(self):
        import pandas as pd
        return pd.DataFrame({"name": self.names, "chi2_p": self.chi2_p, "ecdf_p": self.ecdf_p})


def ranks_of(truth: Mapping[str, float], draws: Mapping[str, np.ndarray], n_draws: int,
             rng: np.random.Generator) -> dict[str, int]:
    """Rank of each true value among ``n_draws`` evenly thinned draws (ties split at random)."""
    out = {}
    for name, value in truth.items():
        d = np.asarray(draws[name], dtype=float).ravel()
        if d.size < n_draws:
            raise ArgumentError("n_draws", n_draws, f"fit returned only {d.size} draws of {name}")
        d = d[np.linspace(0, d.size - 1, n_draws).round().astype(int)]
        below, ties = int(np.sum(d < value)), int(np.sum(d == value))
        out[name] = below + int(rng.integers(0, ties + 1))
    return out


def _one_dataset(seed: int, simulate: Callable, fit: Callable, n_draws: int) -> dict[str, int]:
    rng = np.random.default_rng(seed)
    truth, data = simulate(rng)
    return ranks_of(truth, fit(data, rng), n_draws, rng)


def run_sbc(simulate: Callable, fit: Callable, *, n_datasets: int, seed: int, n_draws: int = 99,
            bins: int | None = None, scheduler: str | None = "serial",
            progress: bool | None = None) -> SBCResult:
    """Run SBC; ``simulate``/``fit`` must be picklable for a distributed ``scheduler``.

    Raises:
        ArgumentError: ``n_datasets`` < 10 or ``n_draws`` < 9.
    """
    if n_datasets < 10:
        raise ArgumentError("n_datasets", n_datasets, "must be >= 10")
    if n_draws < 9:
        raise ArgumentError("n_draws", n_draws, "must be >= 9")
    seeds = np.random.SeedSequence(seed).generate_state(n_datasets).tolist()
    job = partial(_one_dataset, simulate=simulate, fit=fit, n_draws=n_draws)
    rows = map_seeds(job, seeds, scheduler=scheduler, desc="SBC datasets", progress_bar=progress)
    names = tuple(rows[0])
    ranks = np.array([[r[n] for n in names] for r in rows], dtype=int)
    bins = bins or max(2, min(20, n_datasets // 5))
    chi2 = np.array([chi2_uniformity(ranks[:, k], n_draws, bins) for k in range(len(names))])
    rng = np.random.default_rng(seed)
    ecdf = np.array([ecdf_uniformity(ranks[:, k], n_draws, rng)[0] for k in range(len(names))])
    return SBCResult(names=names, ranks=ranks, n_draws=n_draws, chi2_p=chi2, ecdf_p=ecdf)


def chi2_uniformity(ranks: np.ndarray, n_draws: int, bins: int) -> float:
    """Chi-square p-value of ranks (0..n_draws) grouped into ``bins`` near-equal groups."""
    edges = np.linspace(0, n_draws + 1, bins + 1)
    counts = np.histogram(ranks, bins=edges)[0]
    expected = len(ranks) * np.diff(edges) / (n_draws + 1)
    return float(stats.chisquare(counts, expected).pvalue)


def ecdf_uniformity(ranks: np.ndarray, n_draws: int, rng: np.random.Generator, *,
                    n_sim: int = 2000, alpha: float = 0.05, n_eval: int | None = None):
    """Simultaneous-ECDF-band p-value and the (1 − ``alpha``) band.

    Returns:
        (p_value, z (ndarray[k]), lower (ndarray[k]), upper (ndarray[k])): the band on
        the ECDF of fractional ranks at the evaluation points z.
    """
    n = len(ranks)
    k = n_eval or min(n, 50)
    z = np.arange(1, k + 1) / (k + 1)
    frac = (np.asarray(ranks) + 0.5) / (n_draws + 1)

    def statistic(u: np.ndarray) -> np.ndarray:          # u: (..., n) → (...)
        counts = (u[..., None] <= z).sum(axis=-2)
        lo, hi = stats.binom.cdf(counts, n, z), stats.binom.sf(counts - 1, n, z)
        return np.min(2 * np.minimum(lo, hi), axis=-1)

    sim = (rng.integers(0, n_draws + 1, size=(n_sim, n)) + 0.5) / (n_draws + 1)
    null = statistic(sim)
    observed = float(statistic(frac))
    p = float(np.mean(null <= observed))
    gamma = float(np.quantile(null, alpha))
    lower = stats.binom.ppf(gamma / 2, n, z) / n
    upper = stats.binom.ppf(1 - gamma / 2, n, z) / n
    return p, z, lower, upper
