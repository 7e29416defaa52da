"""MCMC backends of M1: PyMC NUTS (every variant) and emcee (no latent variables).

All backends work on the regression form Y = X Bᵀ + E of :mod:`.exact` (rows of B per
output axis) and return numpy draws ``B (chain, draw, p, 3)``, ``sigma (chain, draw, p)``
plus sample statistics; :mod:`.fit` names them (``C``, ``K``, ``sigma_n`` ...).

Variants: ``noise`` "gaussian" or "student" (Student-t with ``nu`` degrees of freedom,
fixed, scale σ); ``eiv`` adds latent stage errors ε_n ~ N(0, stage_sd² I₃) so that the
true inputs are X − ε (errors-in-variables in the commanded displacement). ``noise_sd``
given → σ fixed at it (the known-noise model), else σ_i ~ HalfNormal(sigma_scale).
"""
from __future__ import annotations

import numpy as np

from feeler.calib.matrix.prior import RegressionPrior
from feeler.calib.progress import show_progress

__all__ = ["nuts_model", "sample_nuts", "sample_emcee"]


def nuts_model(x: np.ndarray, y: np.ndarray, prior: RegressionPrior, *, noise: str, nu: float, eiv: bool,
               stage_sd: float, noise_sd: np.ndarray | None):
    """The PyMC model :func:`sample_nuts` samples (``B``, ``sigma``, latent ``eps`` with ``eiv``)."""
    import pymc as pm
    import pytensor.tensor as pt

    n, p = y.shape
    with pm.Model() as model:
        B = pm.Normal("B", mu=prior.b0, sigma=prior.sd, shape=(p, 3))
        if noise_sd is None:
            sigma = pm.HalfNormal("sigma", sigma=prior.sigma_scale, shape=(p,))
        else:
            sigma = pm.Deterministic("sigma", pm.math.constant(np.asarray(noise_sd, float)))
        inputs = x
        if eiv:
            eps = pm.Normal("eps", mu=0.0, sigma=stage_sd, shape=(n, 3))
            inputs = x - eps
        # Σ_k inputs[n, k]·B[i, k] written as a broadcast product and a sum, not pm.math.dot:
        # PyTensor's numba backend (nutpie) takes 46.0 s to compile this model with the Dot op
        # and its gradient on a cold cache, 11.7 s without it (medians, idle; benchmarks/
        # test_bench_nuts.py::test_m1_cold_compile); the sum is the same arithmetic over three terms
        mu = (pt.as_tensor(inputs)[:, None, :] * B[None, :, :]).sum(axis=-1)
        if noise == "student":
            pm.StudentT("y", nu=nu, mu=mu, sigma=sigma, observed=y)
        else:
            pm.Normal("y", mu=mu, sigma=sigma, observed=y)
    return model


def sample_nuts(x: np.ndarray, y: np.ndarray, prior: RegressionPrior, *, noise: str, nu: float,
                eiv: bool, stage_sd: float, noise_sd: np.ndarray | None, chains: int, draws: int,
                tune: int, seed: int, progress: bool | None, cores: int = 1):
    """PyMC NUTS; returns (draws dict, sample_stats dict) as numpy arrays."""
    from feeler.calib.nuts import sample_model, stats_of

    p = y.shape[1]
    model = nuts_model(x, y, prior, noise=noise, nu=nu, eiv=eiv, stage_sd=stage_sd, noise_sd=noise_sd)
    tree = sample_model(model, draws=draws, tune=tune, chains=chains, seed=seed,
                        progress=progress, target_accept=0.9, var_names=["B", "sigma"])
    post = tree["posterior"]
    out = {"B": np.asarray(post["B"].transpose("chain", "draw", ...).values),
           "sigma": np.broadcast_to(np.asarray(post["sigma"].transpose("chain", "draw", ...).values),
                                    (chains, draws, p)).copy()}
    sample_stats = stats_of(tree)
    return out, sample_stats


def _log_posterior(theta: np.ndarray, x, y, prior: RegressionPrior, noise: str, nu: float,
                   noise_sd) -> np.ndarray:
    """log p(B, log σ | y) for walkers ``theta (ndarray[w, 9 + p])`` (vectorised)."""
    from scipy.special import gammaln

    w = theta.shape[0]
    p = y.shape[1]
    B = theta[:, :3 * p].reshape(w, p, 3)
    if noise_sd is None:
        log_sigma = theta[:, 3 * p:]
        sigma = np.exp(log_sigma)
        lp = (-0.5 * (sigma / prior.sigma_scale) ** 2 + log_sigma).sum(axis=1)
    else:
        sigma = np.broadcast_to(np.asarray(noise_sd, float), (w, p))
        log_sigma, lp = np.log(sigma), np.zeros(w)
    lp = lp - 0.5 * (((B - prior.b0) / prior.sd) ** 2).sum(axis=(1, 2))
    z = (y[None] - np.einsum("nk,wik->wni", x, B)) / sigma[:, None, :]
    n = y.shape[0]
    if noise == "student":
        c = gammaln((nu + 1) / 2) - gammaln(nu / 2) - 0.5 * np.log(nu * np.pi)
        ll = n * p * c - (nu + 1) / 2 * np.log1p(z**2 / nu).sum(axis=(1, 2))
    else:
        ll = -0.5 * (z**2).sum(axis=(1, 2)) - 0.5 * n * p * np.log(2 * np.pi)
    return lp + ll - n * log_sigma.sum(axis=1)


def sample_emcee(x: np.ndarray, y: np.ndarray, prior: RegressionPrior, *, noise: str, nu: float,
                 noise_sd: np.ndarray | None, walkers: int, draws: int | None, tune: int, seed: int,
                 progress: bool | None):
    """emcee (affine-invariant ensemble, stretch move); walkers are stored as chains.

    ``draws`` None: run until the chains pass their diagnostics (50 autocorrelation
    times, R-hat, ESS; :mod:`feeler.calib.emcee_run`), discarding the first quarter and
    thinning the rest to every τ_int/4-th step;
    else ``tune`` + ``draws`` steps. Returns (draws, sample_stats, notes)."""
    import emcee

    from feeler.calib.emcee_run import run_until_converged

    rng = np.random.default_rng(seed)
    p = y.shape[1]
    init = _initial_walkers(rng, x, y, prior, noise_sd, walkers)
    ndim = init.shape[1]
    # default stretch move: differential-evolution moves were tried and, with 32 walkers in
    # 12 dimensions, under-dispersed (sds 15 % short of the exact posterior)
    sampler = emcee.EnsembleSampler(walkers, ndim, _log_posterior, vectorize=True,
                                    args=(x, y, prior, noise, nu, noise_sd))
    sampler.random_state = np.random.RandomState(seed).get_state()   # emcee uses the legacy RNG
    notes: list[str] = []
    thin = 1
    if draws is None:
        tune, notes, thin = run_until_converged(sampler, init, progress=progress)
    else:
        sampler.run_mcmc(init, tune + draws, progress=show_progress(progress))
    chain = sampler.get_chain(discard=tune, thin=thin)     # (draw, walker, ndim)
    chain = np.swapaxes(chain, 0, 1)                       # (walker, draw, ndim)
    draws = chain.shape[1]
    B = chain[..., :3 * p].reshape(walkers, draws, p, 3)
    if noise_sd is None:
        sigma = np.exp(chain[..., 3 * p:])
    else:
        sigma = np.broadcast_to(np.asarray(noise_sd, float), (walkers, draws, p)).copy()
    lp = np.swapaxes(sampler.get_log_prob(discard=tune, thin=thin), 0, 1)
    return {"B": B, "sigma": sigma}, {"lp": lp}, notes


def _initial_walkers(rng, x, y, prior: RegressionPrior, noise_sd, walkers: int) -> np.ndarray:
    """Walkers spread like the least-squares sampling distribution (ridge-stabilised)."""
    p = y.shape[1]
    G = x.T @ x + np.eye(3) / prior.sd**2
    coef = np.linalg.solve(G, x.T @ y + prior.b0.T / prior.sd**2)      # (3, p)
    resid = y - x @ coef
    sd_y = np.maximum(resid.std(axis=0), 1e-9 * prior.sigma_scale)
    cov = np.linalg.inv(G)
    L = np.linalg.cholesky(cov)
    b = coef.T[None] + np.einsum("ij,wpj->wpi", L, rng.standard_normal((walkers, p, 3))) * sd_y[None, :, None]
    parts = [b.reshape(walkers, 3 * p)]
    if noise_sd is None:
        dof = max(x.shape[0] - 3, 1)
        parts.append(np.log(sd_y)[None] + rng.standard_normal((walkers, p)) / np.sqrt(2 * dof))
    return np.concatenate(parts, axis=1)
