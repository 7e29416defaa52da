"""Exact draws of the plate parameters (μ_c, σ_c) given τ, for every noise model.

Conjugacy (Gelman et al., BDA3 §3.3, per plate): with μ_c | σ_c ~ Normal(m0_c, σ_c²/κ₀)
(flat when κ₀ = 0) the mean integrates out and each plate leaves

    (σ_c²)^(−r_c/2) · exp(−Q_c / (2σ_c²)),   r_c = n_c − 1 + [κ₀ > 0],
    Q_c = SS_c + κ₀ n_c/(κ₀ + n_c) · (x̄_c − m0_c)².

- ``per-plate``: σ_c² ~ scaled-inv-χ²(ν₀ + r_c, (ν₀ s₀² + Q_c)/(ν₀ + r_c)) each;
- ``constant``:  σ² ~ scaled-inv-χ²(ν₀ + Σr, (ν₀ s₀² + ΣQ)/(ν₀ + Σr));
- ``growing``:   σ_c = σ₀ e^(g x_c); σ₀² integrates out to
  p(g | data) ∝ exp(−g Σ_c x_c r_c) · (ν₀ s₀² + Σ_c Q_c e^(−2 g x_c))^(−(ν₀ + Σr)/2) on
  g ∈ [−g_max, g_max], tabulated on ``G_NODES`` cells (drawn by mass, jittered in the
  cell), then σ₀² | g is scaled-inv-χ² as in ``constant``.

Then μ_c | σ_c ~ Normal((κ₀ m0_c + n_c x̄_c)/(κ₀ + n_c), σ_c²/(κ₀ + n_c)). Every array
carries a leading draw axis, because each draw has its own τ and so its own statistics.
"""
from __future__ import annotations

import numpy as np

from feeler.calib.neuron.model import Plates, PlatePrior

__all__ = ["draw_plate_parameters", "growth_log_density", "G_NODES", "Q_FLOOR"]

G_NODES = 121
Q_FLOOR = 1e-30     # relative floor of Q (zero-spread plates: finite draws, flagged by the checks)


def _q_r(mean, ss, plates: Plates, prior: PlatePrior):
    n = plates.counts.astype(float)
    r = n - 1 + (1.0 if prior.kappa0 > 0 else 0.0)
    q = np.asarray(ss, float)
    if prior.kappa0 > 0:
        q = q + prior.kappa0 * n / (prior.kappa0 + n) * (mean - np.asarray(prior.m0, float)) ** 2
    scale = np.maximum(np.max(np.abs(mean), axis=-1, keepdims=True), np.finfo(float).tiny)
    return np.maximum(q, Q_FLOOR * scale ** 2), r


def growth_log_density(g: np.ndarray, q: np.ndarray, r: np.ndarray, x: np.ndarray, prior: PlatePrior) -> np.ndarray:
    """log p(g | data) + const for ``g (ndarray[G])`` and ``q (ndarray[S, C])`` → ndarray[S, G]."""
    total = prior.nu0 * prior.s0_sq + np.einsum("sc,gc->sg", q, np.exp(-2.0 * g[:, None] * x[None, :]))
    total = np.maximum(total, np.finfo(float).tiny)            # zero spread: finite, flagged by the checks
    return -g[None, :] * float(np.sum(x * r)) - 0.5 * (prior.nu0 + np.sum(r)) * np.log(total)


def _inv_chi2(rng, dof, numerator):
    """σ² draws: numerator / χ²_dof (numerator = dof · scale)."""
    return numerator / rng.chisquare(dof, size=np.shape(numerator))


def draw_plate_parameters(rng: np.random.Generator, mean: np.ndarray, ss: np.ndarray, plates: Plates,
                          noise: str, prior: PlatePrior, growth_max: float = 3.0) -> dict:
    """One draw of (μ, σ) per row of the statistics.

    Args:
        mean, ss (ndarray[S, C]): per-plate mean and within-plate sum of squares of P.
        noise (str): one of ``constant``, ``growing``, ``per-plate``.
    Returns:
        dict ``mu``, ``sigma`` (ndarray[S, C]) and ``growth`` (ndarray[S]; zeros unless growing).
    """
    q, r = _q_r(mean, ss, plates, prior)
    S, C = q.shape
    x = plates.x
    growth = np.zeros(S)
    if noise == "per-plate":
        sigma = np.sqrt(_inv_chi2(rng, prior.nu0 + r[None, :] + np.zeros((S, C)), prior.nu0 * prior.s0_sq + q))
    else:
        if noise == "growing":
            nodes = np.linspace(-growth_max, growth_max, G_NODES)
            lp = growth_log_density(nodes, q, r, x, prior)
            w = np.exp(lp - lp.max(axis=1, keepdims=True))
            cdf = np.cumsum(w, axis=1)
            idx = np.minimum((cdf < rng.uniform(size=S)[:, None] * cdf[:, -1:]).sum(axis=1), G_NODES - 1)
            step = nodes[1] - nodes[0]
            growth = nodes[idx] + rng.uniform(-0.5, 0.5, S) * step
            growth = np.where(growth > growth_max, 2 * growth_max - growth, growth)
            growth = np.where(growth < -growth_max, -2 * growth_max - growth, growth)
        shape = np.exp(growth[:, None] * x[None, :])                             # σ_c / σ₀
        s0_sq = _inv_chi2(rng, np.full(S, prior.nu0 + np.sum(r)),
                          prior.nu0 * prior.s0_sq + np.sum(q / shape ** 2, axis=1))
        sigma = np.sqrt(s0_sq)[:, None] * shape
    n = plates.counts.astype(float)
    kn = prior.kappa0 + n
    centre = (prior.kappa0 * np.asarray(prior.m0 or np.zeros(C), float) + n * mean) / kn
    mu = centre + sigma / np.sqrt(kn) * rng.standard_normal((S, C))
    return {"mu": mu, "sigma": sigma, "growth": growth}
