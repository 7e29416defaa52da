"""R-hat, effective sample sizes and Monte Carlo standard errors with NumPy alone.

The definitions of Vehtari, Gelman, Simpson, Carpenter & Bürkner (2021), "Rank-
normalization, folding, and localization: an improved R-hat", as ArviZ 1.x computes
them (rank-normalised split R-hat, the larger of bulk and folded; bulk ESS on rank-
normalised split chains; tail ESS the smaller of the 5 % and 95 % quantile ESS; MCSE of
the mean and sd). Written here so that a fit's summary needs neither SciPy nor
arviz-stats, whose imports take seconds (issue 18: an exact fit answers in ~2 s).
``tests/calib/test_convergence.py`` checks every function against arviz-stats.

Every function takes ``x (ndarray[chain, draw])`` and returns a float; NaN when ``x``
holds a NaN or has fewer than 4 draws (R-hat: or fewer than 2 chains).
"""
from __future__ import annotations

from functools import lru_cache
from statistics import NormalDist

import numpy as np

__all__ = ["rhat", "ess_bulk", "ess_tail", "ess_mean", "mcse_mean", "mcse_sd"]

_BLOM = 3 / 8        # fractional offset of the rank back-transform (Blom 1958)


def _invalid(x: np.ndarray, min_chains: int) -> bool:
    return x.ndim != 2 or x.shape[0] < min_chains or x.shape[1] < 4 or bool(np.isnan(x).any())


def _split(x: np.ndarray) -> np.ndarray:
    """(2·chain, draw // 2): each chain's first and last halves as separate chains."""
    half = x.shape[1] // 2
    return np.vstack((x[:, :half], x[:, -half:]))


@lru_cache(maxsize=16)
def _normal_scores(size: int) -> np.ndarray:
    """Φ⁻¹((r − 3/8) / (size + 1/4)) for every average rank r = 1, 1.5, ..., size (index 2r − 2)."""
    ppf = NormalDist().inv_cdf
    ranks = 1.0 + 0.5 * np.arange(2 * size - 1)
    return np.array([ppf(p) for p in (ranks - _BLOM) / (size - 2 * _BLOM + 1)])


def _z_scale(x: np.ndarray) -> np.ndarray:
    """Rank-normalised ``x`` (ties share their average rank), same shape."""
    flat = x.ravel()
    _, inverse, counts = np.unique(flat, return_inverse=True, return_counts=True)
    below = np.cumsum(counts) - counts
    twice_rank = (2 * below + counts + 1)[inverse]             # 2 × average rank, an integer
    return _normal_scores(flat.size)[twice_rank - 2].reshape(x.shape)


def _rhat_plain(x: np.ndarray) -> float:
    n = x.shape[1]
    between = n * np.var(x.mean(axis=1), ddof=1)
    within = np.mean(np.var(x, axis=1, ddof=1))
    return float(np.sqrt((between / within + n - 1) / n))


def _autocov(x: np.ndarray) -> np.ndarray:
    """Autocovariance of each chain at every lag, (chain, draw), biased (divided by draw)."""
    n = x.shape[1]
    centred = x - x.mean(axis=1, keepdims=True)
    f = np.fft.rfft(centred, n=2 * n, axis=1)
    return np.fft.irfft(f * np.conjugate(f), n=2 * n, axis=1)[:, :n] / n


def _ess(x: np.ndarray) -> float:
    """ESS of (chain, draw) ``x`` by Geyer's initial monotone sequence estimator."""
    x = np.asarray(x, dtype=float)
    if np.max(x) - np.min(x) < np.finfo(float).resolution:
        return float(x.size)
    m, n = x.shape
    acov = _autocov(x)
    mean_var = np.mean(acov[:, 0]) * n / (n - 1.0)
    var_plus = mean_var * (n - 1.0) / n + (np.var(x.mean(axis=1), ddof=1) if m > 1 else 0.0)
    rho = np.zeros(n)
    rho_even, rho_odd = 1.0, 1.0 - (mean_var - np.mean(acov[:, 1])) / var_plus
    rho[0], rho[1] = rho_even, rho_odd
    t = 1
    while t < n - 3 and rho_even + rho_odd > 0.0:            # initial positive sequence
        rho_even = 1.0 - (mean_var - np.mean(acov[:, t + 1])) / var_plus
        rho_odd = 1.0 - (mean_var - np.mean(acov[:, t + 2])) / var_plus
        if rho_even + rho_odd >= 0:
            rho[t + 1], rho[t + 2] = rho_even, rho_odd
        t += 2
    max_t = t - 2
    if rho_even > 0:
        rho[max_t + 1] = rho_even
    t = 1
    while t <= max_t - 2:                                      # made monotone
        if rho[t + 1] + rho[t + 2] > rho[t - 1] + rho[t]:
            rho[t + 1] = rho[t + 2] = (rho[t - 1] + rho[t]) / 2.0
        t += 2
    total = m * n
    tau = -1.0 + 2.0 * np.sum(rho[: max_t + 1]) + np.sum(rho[max_t + 1: max_t + 2])
    tau = max(tau, 1 / np.log10(total))
    return float("nan") if np.isnan(rho).any() else float(total / tau)


def rhat(x: np.ndarray) -> float:
    """Rank-normalised split R-hat: the larger of the bulk and the folded (tail) R-hat."""
    x = np.asarray(x, dtype=float)
    if _invalid(x, 2):
        return float("nan")
    s = _split(x)
    return max(_rhat_plain(_z_scale(s)), _rhat_plain(_z_scale(np.abs(s - np.median(s)))))


def ess_bulk(x: np.ndarray) -> float:
    """Bulk ESS: ESS of the rank-normalised split chains."""
    x = np.asarray(x, dtype=float)
    return float("nan") if _invalid(x, 1) else _ess(_z_scale(_split(x)))


def ess_tail(x: np.ndarray, prob: tuple[float, float] = (0.05, 0.95)) -> float:
    """Tail ESS: the smaller ESS of the indicators x ≤ q(prob[0]) and x ≤ q(prob[1])."""
    x = np.asarray(x, dtype=float)
    if _invalid(x, 1):
        return float("nan")
    return min(_ess(_split(x <= np.quantile(x, p))) for p in prob)


def ess_mean(x: np.ndarray) -> float:
    """ESS of the mean: ESS of the split chains (no rank normalisation)."""
    x = np.asarray(x, dtype=float)
    return float("nan") if _invalid(x, 1) else _ess(_split(x))


def mcse_mean(x: np.ndarray) -> float:
    """Monte Carlo standard error of the posterior mean: sd / √ESS_mean."""
    x = np.asarray(x, dtype=float)
    return float("nan") if _invalid(x, 1) else float(np.std(x, ddof=1) / np.sqrt(ess_mean(x)))


def mcse_sd(x: np.ndarray) -> float:
    """Monte Carlo standard error of the posterior sd (delta method on the variance)."""
    x = np.asarray(x, dtype=float)
    if _invalid(x, 1):
        return float("nan")
    centred = x - x.mean()
    ess = ess_mean(centred ** 2)
    var = (centred ** 2).mean()
    return float(np.sqrt(((centred ** 4).mean() - var ** 2) / ess / var / 4))
