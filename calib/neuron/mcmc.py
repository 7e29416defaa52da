"""MCMC backends of M2: PyMC NUTS (τ continuous through the interpolated peak table) and emcee.

Both sample (ln a, ln τ, h, ln σ) under the priors of :class:`Priors` and the likelihood
of :mod:`.model`; NUTS reads P(τ) from the same log-τ table, interpolated linearly inside
the pytensor graph (piecewise-linear in ln τ, so gradients exist everywhere).
"""
from __future__ import annotations

import numpy as np

from feeler.calib.neuron.model import PeakTable, Priors, log_likelihood, log_prior
from feeler.calib.progress import show_progress

__all__ = ["sample_nuts", "sample_emcee"]


def sample_nuts(table: PeakTable, delta_mm, pri: Priors, *, chains: int, draws: int, tune: int,
                seed: int, progress: bool | None, cores: int = 1):
    """PyMC NUTS; returns (draws dict ``name -> (chain, draw)``, sample_stats dict)."""
    import pymc as pm
    import pytensor.tensor as pt

    lt = table.log_tau
    step, n_grid = float(lt[1] - lt[0]), len(lt)
    peak_t = pt.constant(np.ascontiguousarray(table.peak.T))
    with pm.Model() as model:
        log_tau = pm.Uniform("log_tau", lower=np.log(pri.tau_lo_s), upper=np.log(pri.tau_hi_s))
        log_a = pm.Normal("log_a", mu=pri.log_a_mu, sigma=pri.log_a_sd)
        h = pm.HalfNormal("h", sigma=pri.h_scale_mm)
        sigma = pm.HalfNormal("sigma_mm", sigma=pri.sigma_scale_mm)
        pos = pt.clip((log_tau - lt[0]) / step, 0.0, n_grid - 1.0)
        i = pt.minimum(pt.cast(pt.floor(pos), "int64"), n_grid - 2)
        w = pos - i
        peak = peak_t[i] * (1.0 - w) + peak_t[i + 1] * w
        mu = pt.maximum(pt.exp(log_a) * peak - h, 0.0)
        pm.Normal("delta", mu=mu, sigma=sigma, observed=np.asarray(delta_mm, float))
        pm.Deterministic("a", pt.exp(log_a))
        pm.Deterministic("tau_s", pt.exp(log_tau))
        tree = pm.sample(draws=draws, tune=tune, chains=chains, cores=cores, random_seed=seed,
                         progressbar=show_progress(progress), target_accept=0.9,
                         compute_convergence_checks=False, model=model)
    post = tree["posterior"]
    out = {k: np.asarray(post[k].transpose("chain", "draw").values) for k in ("a", "tau_s", "h", "sigma_mm")}
    stats = tree["sample_stats"]
    sample_stats = {"diverging": np.asarray(stats["diverging"].transpose("chain", "draw").values),
                    "lp": np.asarray(stats["lp"].transpose("chain", "draw").values)}
    return out, sample_stats


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
