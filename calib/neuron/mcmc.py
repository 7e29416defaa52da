"""MCMC backends of M2: PyMC NUTS with τ integrated out, and emcee.

Why NUTS does not sample ln τ directly: along ln τ the posterior can be a comb, not a
bump. When a scan's largest change sits in one frame early in the record (a start
transient: an earlier four-plates scene had the stage's breakaway in its first frame),
a window at sample t_k takes in that frame only once τ reaches t_k − t_0, so every
0.5 s (one frame) the peaks P_k jump up by several % within a fraction of a frame and
the log posterior drops by 3–5 (the earlier scene: 14 teeth between τ = 3 and 10 s).
A leapfrog step must resolve that sub-frame wall, and crossing it costs 3–5 units of
energy: NUTS on (ln a, ln τ, h, ln σ) gave R-hat 1.5 and bulk ESS 8 for τ at 4 × 1000.
``tests/calib/test_neuron_fit.py`` builds such a record and checks the wall and the
collapsed quadrature below against the exact core.
The wall is in the exact neuron core (not an interpolation artefact), so the remedy is
not to smooth the model but to integrate τ out:

    p(δ | a, h, σ) = ∫ p(δ | a, τ, h, σ) p(ln τ) d ln τ

by the trapezoid rule on ``SUB`` sub-nodes per cell of the log-τ table (P is linear in
ln τ inside a cell, exactly as in every backend). NUTS samples the smooth collapsed
posterior of (ln a, h, ln σ); each draw then gets τ from its exact conditional on the
same sub-nodes (a sub-cell picked by its weight, jittered uniformly inside it). The
model is unchanged; only the τ quadrature (sub-cell 1/``SUB`` of a table cell) is an
approximation, of the same kind as the grid backend's τ axis.
"""
from __future__ import annotations

import numpy as np

from feeler.calib.neuron.model import PeakTable, Priors, log_likelihood, log_prior
from feeler.calib.progress import show_progress

__all__ = ["sample_nuts", "sample_emcee", "tau_nodes", "SUB"]

SUB = 4           # quadrature sub-nodes per cell of the log-τ table


def tau_nodes(table: PeakTable, sub: int = SUB):
    """Quadrature nodes of ln τ: (x ndarray[m], log trapezoid weights ndarray[m] of the
    normalised uniform prior, P ndarray[m, n_scans] linearly interpolated from ``table``)."""
    lt = table.log_tau
    x = np.linspace(lt[0], lt[-1], sub * (lt.size - 1) + 1)
    w = np.full(x.size, 1.0 / (x.size - 1))
    w[[0, -1]] *= 0.5
    return x, np.log(w), table.at(np.exp(x))


def _tau_log_weights(p_nodes, log_w, delta_mm, a, h, sigma):
    """log p(τ-node | δ, a, h, σ) + const for draws a, h, σ ndarray[n] → ndarray[n, m]."""
    mu = np.maximum(a[:, None, None] * p_nodes[None] - h[:, None, None], 0.0)     # (n, m, scans)
    ss = np.sum((delta_mm - mu) ** 2, axis=-1)
    return log_w - 0.5 * ss / sigma[:, None] ** 2


def draw_tau(x_nodes, log_w, p_nodes, delta_mm, a, h, sigma, rng: np.random.Generator,
             chunk: int = 256) -> np.ndarray:
    """ln τ per draw from its conditional on the nodes (ndarray[n]); a, h, σ ndarray[n]."""
    step = x_nodes[1] - x_nodes[0]
    out = np.empty(a.size)
    for s in range(0, a.size, chunk):
        sl = slice(s, s + chunk)
        lw = _tau_log_weights(p_nodes, log_w, delta_mm, a[sl], h[sl], sigma[sl])
        pr = np.exp(lw - lw.max(axis=1, keepdims=True))
        cdf = np.cumsum(pr, axis=1)
        u = rng.uniform(size=cdf.shape[0]) * cdf[:, -1]
        idx = np.minimum((cdf < u[:, None]).sum(axis=1), x_nodes.size - 1)
        out[sl] = x_nodes[idx] + rng.uniform(-0.5, 0.5, idx.size) * step
    lo, hi = x_nodes[0], x_nodes[-1]
    out = np.where(out < lo, 2 * lo - out, out)            # reflect the jitter at the prior bounds
    return np.where(out > hi, 2 * hi - out, out)


def sample_nuts(table: PeakTable, delta_mm, pri: Priors, *, chains: int, draws: int, tune: int,
                seed: int, progress: bool | None, cores: int = 1, target_accept: float = 0.95):
    """PyMC NUTS on (ln a, h, ln σ) with τ integrated out, then τ from its conditional.

    Returns (draws dict ``name -> ndarray (chain, draw)``, sample_stats dict with
    ``diverging`` and ``lp``)."""
    import pymc as pm
    import pytensor.tensor as pt

    from feeler.calib.nuts import sample_model, stats_of

    d = np.asarray(delta_mm, float)
    x, log_w, p_nodes = tau_nodes(table)
    p_c, lw_c = pt.constant(np.ascontiguousarray(p_nodes)), pt.constant(log_w)
    with pm.Model() as model:
        log_a = pm.Normal("log_a", mu=pri.log_a_mu, sigma=pri.log_a_sd)
        h = pm.HalfNormal("h", sigma=pri.h_scale_mm)
        sigma = pm.HalfNormal("sigma_mm", sigma=pri.sigma_scale_mm)
        a = pm.Deterministic("a", pt.exp(log_a))
        mu = pt.maximum(a * p_c - h, 0.0)                                      # (m, scans)
        ll = -d.size * pt.log(sigma) - 0.5 * pt.sum((d - mu) ** 2, axis=1) / sigma ** 2
        pm.Potential("lik_tau_integrated", pt.logsumexp(ll + lw_c))
        tree = sample_model(model, draws=draws, tune=tune, chains=chains, seed=seed,
                            progress=progress, target_accept=target_accept)
    post = tree["posterior"]
    out = {k: np.asarray(post[k].transpose("chain", "draw").values) for k in ("a", "h", "sigma_mm")}
    rng = np.random.default_rng([int(seed), 2])
    lt = draw_tau(x, log_w, p_nodes, d, out["a"].ravel(), out["h"].ravel(), out["sigma_mm"].ravel(), rng)
    out["tau_s"] = np.exp(lt).reshape(out["a"].shape)
    sample_stats = stats_of(tree)
    return {k: out[k] for k in ("a", "tau_s", "h", "sigma_mm")}, sample_stats


def _log_prob(theta: np.ndarray, table: PeakTable, delta_mm, pri: Priors) -> np.ndarray:
    """log posterior for walkers ``theta (ndarray[w, 4])`` = (ln a, ln τ, h, ln σ)."""
    log_a, log_tau, h, log_sigma = theta.T
    lp = log_prior(pri, log_a, log_tau, h, log_sigma)
    ok = np.isfinite(lp)
    out = np.full(theta.shape[0], -np.inf)
    if ok.any():
        out[ok] = lp[ok] + log_likelihood(table, delta_mm, np.exp(log_a[ok]), np.exp(log_tau[ok]),
                                          h[ok], np.exp(log_sigma[ok]))
    return out


def sample_emcee(table: PeakTable, delta_mm, pri: Priors, *, walkers: int, steps: int,
                 start: dict, rng: np.random.Generator, progress: bool | None):
    """emcee (stretch move, vectorised); ``start`` holds ≥ ``walkers`` initial draws per
    parameter. The first quarter of the steps is discarded. Returns (draws, sample_stats)
    with walkers as chains."""
    import emcee

    pick = rng.choice(np.asarray(start["a"]).size, size=walkers, replace=False)
    p0 = np.column_stack([np.log(np.ravel(start["a"])[pick]), np.log(np.ravel(start["tau_s"])[pick]),
                          np.ravel(start["h"])[pick], np.log(np.ravel(start["sigma_mm"])[pick])])
    sampler = emcee.EnsembleSampler(walkers, 4, _log_prob, args=(table, delta_mm, pri), vectorize=True)
    sampler.random_state = np.random.RandomState(int(rng.integers(2 ** 31))).get_state()  # legacy RNG
    sampler.run_mcmc(p0, steps, progress=show_progress(progress))
    chain = sampler.get_chain(discard=steps // 4)            # (step, walker, 4)
    x = np.transpose(chain, (1, 0, 2))
    draws = {"a": np.exp(x[..., 0]), "tau_s": np.exp(x[..., 1]), "h": x[..., 2], "sigma_mm": np.exp(x[..., 3])}
    lp = sampler.get_log_prob(discard=steps // 4).T
    return draws, {"lp": lp}
