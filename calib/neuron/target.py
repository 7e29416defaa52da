"""The M2 posterior as one density for the MCMC backends (NUTS and emcee).

The exact backend draws τ from its weights and then the plates from their conjugate
posterior at that τ. MCMC needs coordinates that mean the same thing at every τ, so the
plate parameters are taken in mm of decoded height: at a window τ the scans' peaks are
mapped by the line z = a_τ·P − h_τ through the plates' *sample* means (a fixed function
of the data and τ), and the parameters are the plate means m_c (mm) and log sds
l_c = ln s_c (mm; ``constant``: one l, ``growing``: l₀ + g·x_c). Under the reference
prior the conditional posterior at τ is then, exactly and normalised,

    log p(m, l | τ) = K_τ − Σ_c [r_c l_c + ½ Q_c e^(−2 l_c)]
                          + Σ_c [½ ln(n_c / 2π) − l_c − ½ n_c (m_c − z̄_c)² e^(−2 l_c)]

with z̄_c, Q_c the plate's sample mean (mm) and sum of squares (mm²) at τ, r_c = n_c − 1
and K_τ the normaliser of the σ part (closed form for ``per-plate`` and ``constant``; for
``growing`` a one-dimensional quadrature over g, whose density ∝ e^(−g Σx r)·Q(g)^(−Σr/2)).
The joint density is weights(τ) × this; NUTS integrates τ out by quadrature over
``SUB`` sub-nodes per cell and draws τ afterwards from its conditional, emcee samples
ln τ directly. Converting back: μ_c = (m_c + h_τ)/a_τ, σ_c = s_c/a_τ (units of P).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import gammaln, logsumexp

from feeler.calib.neuron.conjugate import G_NODES
from feeler.calib.neuron.model import PeakTable, Plates, decoder_line, plate_stats

__all__ = ["NodeStats", "node_stats", "log_conditional", "n_spread", "SUB", "spreads"]

SUB = 4           # quadrature sub-nodes per cell of the log-τ table


@dataclass(frozen=True)
class NodeStats:
    """Per τ (ndarray[m]): log τ, log weight (density × width), line (a, h); per τ and
    plate (ndarray[m, C]): sample mean z̄ (mm) and sum of squares Q (mm²); K (ndarray[m])."""
    log_tau: np.ndarray
    log_w: np.ndarray
    a: np.ndarray
    h: np.ndarray
    zbar: np.ndarray
    q: np.ndarray
    k: np.ndarray


def n_spread(noise: str, n_plates: int) -> int:
    """Spread parameters: C (per-plate), 1 (constant), 2 (growing: l₀ and g)."""
    return {"per-plate": n_plates, "constant": 1, "growing": 2}[noise]


def spreads(theta_s, noise: str, x):
    """Per-plate log sds l_c (…, C) from the spread parameters ``theta_s (…, k)`` (numpy
    or pytensor; ``x (ndarray[C])`` the plates' positions)."""
    x = np.asarray(x, float)
    if noise == "per-plate":
        return theta_s
    if noise == "constant":
        return theta_s[..., :1] + 0.0 * x
    return theta_s[..., :1] + theta_s[..., 1:2] * x


def _normaliser(q: np.ndarray, plates: Plates, noise: str, growth_max: float) -> np.ndarray:
    r = plates.counts - 1.0
    if noise == "per-plate":
        return np.sum(0.5 * r * np.log(q / 2) - gammaln(r / 2) + np.log(2), axis=-1)
    nu = float(np.sum(r))
    if noise == "constant":
        return 0.5 * nu * np.log(np.sum(q, axis=-1) / 2) - gammaln(nu / 2) + np.log(2)
    g = np.linspace(-growth_max, growth_max, G_NODES)
    qg = np.einsum("mc,gc->mg", q, np.exp(-2 * g[:, None] * plates.x[None, :]))
    lp = -g[None, :] * float(np.sum(plates.x * r)) - 0.5 * nu * np.log(qg / 2)
    wts = np.full(G_NODES, g[1] - g[0])
    wts[[0, -1]] *= 0.5
    return -logsumexp(lp + np.log(wts), axis=-1) - gammaln(nu / 2) + np.log(2)


def node_stats(table: PeakTable, plates: Plates, log_tau: np.ndarray, log_w: np.ndarray, noise: str,
               growth_max: float = 3.0) -> NodeStats:
    """Statistics at the windows ``log_tau (ndarray[m])`` with weights ``log_w``."""
    mean, ss = plate_stats(table.at(np.exp(log_tau)), plates)                  # (m, C) in P units
    a, h = decoder_line(mean, plates)
    zbar = a[:, None] * mean - h[:, None]
    q = np.maximum(a[:, None] ** 2 * ss, 1e-30 * np.max(np.abs(zbar), axis=1, keepdims=True) ** 2)
    return NodeStats(log_tau=log_tau, log_w=log_w, a=a, h=h, zbar=zbar, q=q,
                     k=_normaliser(q, plates, noise, growth_max))


def quadrature(table: PeakTable, plates: Plates, log_w_cells: np.ndarray, noise: str, growth_max: float = 3.0,
               sub: int = SUB, min_weight: float = 1e-12) -> NodeStats:
    """``sub`` sub-nodes per cell of the table (cells below ``min_weight`` × the largest
    dropped); the half cells past the table's ends are reflected inside, as the exact
    backend reflects its jitter."""
    lt = table.log_tau
    step = lt[1] - lt[0]
    keep = np.flatnonzero(log_w_cells >= np.max(log_w_cells) + np.log(min_weight))
    offs = (np.arange(sub) + 0.5) / sub - 0.5
    x = (lt[keep][:, None] + offs[None, :] * step).ravel()
    x = np.where(x < lt[0], 2 * lt[0] - x, np.where(x > lt[-1], 2 * lt[-1] - x, x))
    w = np.repeat(log_w_cells[keep], sub) - np.log(sub)
    return node_stats(table, plates, x, w, noise, growth_max)


def log_conditional(m, theta_s, st_zbar, st_q, st_k, plates: Plates, noise: str, xp=np):
    """log p(m, spread parameters | τ) for parameters ``m (…, C)``, ``theta_s (…, k)`` and
    node statistics ``st_zbar, st_q (…, C)``, ``st_k (…)``; broadcasting; ``xp`` numpy or
    pytensor.tensor."""
    n = np.asarray(plates.counts, float)
    r = n - 1.0
    lc = spreads(theta_s, noise, plates.x)
    inv = xp.exp(-2.0 * lc)
    sd_part = -xp.sum(r * lc + 0.5 * st_q * inv, axis=-1)
    mean_part = xp.sum(0.5 * np.log(n / (2 * np.pi)) - lc - 0.5 * n * (m - st_zbar) ** 2 * inv, axis=-1)
    return st_k + sd_part + mean_part
