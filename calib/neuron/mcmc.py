"""MCMC backends of M2: PyMC NUTS with τ integrated out, and emcee on (ln τ, plates).

Both sample the density of :mod:`.target`. Why NUTS does not sample ln τ directly: along
ln τ the posterior can be a comb, not a bump. When a scan's largest change sits in one
frame early in the record (a start transient), a window at sample t_k takes in that frame
only once τ reaches t_k − t_0, so every frame the peaks P_k jump within a fraction of a
frame and the weights of τ jump with them (an earlier four-plates scene had 14 teeth
between τ = 3 and 10 s). A leapfrog step must resolve that sub-frame wall:
``tests/calib/test_neuron_fit.py`` builds such a record and checks the wall against the
exact core. The wall is in the exact neuron core (not an interpolation artefact), so the
remedy is not to smooth the model but to integrate τ out by quadrature on ``SUB``
sub-nodes per cell of the log-τ table: NUTS samples the plates (smooth in mm
coordinates), and each draw then gets τ from its exact conditional on the sub-nodes
(picked by weight, jittered inside its sub-cell). emcee samples ln τ directly and runs
until its chains are 50 autocorrelation times long (:mod:`feeler.calib.emcee_run`).
Only the reference prior is supported here (the exact backend takes any conjugate prior).
"""
from __future__ import annotations

import numpy as np

from feeler.calib.neuron.grid import named_draws, sample_grid
from feeler.calib.neuron.model import PeakTable, Plates, Priors
from feeler.calib.neuron.target import SUB, log_conditional, n_spread, node_stats, quadrature, spreads
from feeler.calib.progress import show_progress
from feeler.errors import ArgumentError

__all__ = ["sample_nuts", "sample_emcee", "draw_tau_given", "SUB"]


def _reference_only(pri: Priors) -> None:
    if pri.plate.nu0 or pri.plate.kappa0:
        raise ArgumentError("priors", "a proper plate prior", "the reference prior with nuts/emcee (use grid)")


def _to_named(tau, m, theta_s, a_tau, h_tau, plates: Plates, noise: str) -> dict:
    lc = spreads(theta_s, noise, plates.x)
    mu = (m + h_tau[:, None]) / a_tau[:, None]
    sigma = np.exp(lc) / a_tau[:, None]
    growth = theta_s[:, 1] if noise == "growing" else np.zeros(m.shape[0])
    return named_draws(tau, mu, sigma, growth, plates, noise)


def draw_tau_given(nodes, m, theta_s, plates: Plates, noise: str, rng: np.random.Generator, chunk: int = 256):
    """Index of the sub-node of each draw from p(τ | plates) ∝ w(τ)·p(plates | τ): ndarray[n]."""
    out = np.empty(m.shape[0], int)
    for s in range(0, m.shape[0], chunk):
        sl = slice(s, s + chunk)
        lp = nodes.log_w + log_conditional(m[sl, None, :], theta_s[sl, None, :], nodes.zbar, nodes.q, nodes.k,
                                           plates, noise)
        pr = np.exp(lp - lp.max(axis=1, keepdims=True))
        cdf = np.cumsum(pr, axis=1)
        u = rng.uniform(size=cdf.shape[0]) * cdf[:, -1]
        out[sl] = np.minimum((cdf < u[:, None]).sum(axis=1), nodes.log_tau.size - 1)
    return out


def _start(table, plates, pri, noise, log_w, n, rng):
    """``n`` exact draws in MCMC coordinates (ln τ, m, spread parameters)."""
    g = sample_grid(table, plates, pri, noise, log_w, chains=1, draws=n, rng=rng)
    tau = np.ravel(g["tau_s"])
    st = node_stats(table, plates, np.log(tau), np.zeros(tau.size), noise, pri.growth_max)
    a_ratio = st.a / np.ravel(g["a"])                       # sample line vs drawn line, per draw
    m = a_ratio[:, None] * (g["plate_mean_mm"].reshape(n, -1) + np.ravel(g["h"])[:, None]) - st.h[:, None]
    sd = a_ratio[:, None] * g["plate_sd_mm"].reshape(n, -1)
    if noise == "per-plate":
        theta = np.log(sd)
    elif noise == "constant":
        theta = np.log(sd[:, :1])
    else:
        theta = np.column_stack([np.log(sd[:, 0]), np.ravel(g["growth"])])
    return np.log(tau), m, theta


def sample_nuts(table: PeakTable, plates: Plates, pri: Priors, noise: str, log_w: np.ndarray, *, chains: int,
                draws: int, tune: int, seed: int, progress: bool | None, cores: int = 1, target_accept: float = 0.9):
    """PyMC NUTS on the plates with τ integrated out, then τ from its conditional.

    Returns (draws dict ``name -> ndarray (chain, draw[, C])``, sample_stats dict with
    ``diverging`` and ``lp``)."""
    import pymc as pm
    import pytensor.tensor as pt

    from feeler.calib.nuts import sample_model, stats_of

    _reference_only(pri)
    C, k = plates.steps_mm.size, n_spread(noise, plates.steps_mm.size)
    nodes = quadrature(table, plates, log_w, noise, pri.growth_max)
    rng = np.random.default_rng([int(seed), 1])
    _, m0, th0 = _start(table, plates, pri, noise, log_w, chains, rng)
    with pm.Model() as model:
        # the chains start near the exact posterior (nutpie jitters the start in each chain)
        m = pm.Flat("m", shape=C, initval=m0.mean(axis=0))
        if noise == "growing":
            l0 = pm.Flat("l0", shape=1, initval=th0[:, :1].mean(axis=0))
            g = pm.Uniform("growth", -pri.growth_max, pri.growth_max, shape=1, initval=th0[:, 1:].mean(axis=0))
            theta = pt.concatenate([l0, g])
        else:
            theta = pm.Flat("l", shape=k, initval=th0.mean(axis=0))
        lp = log_conditional(m[None, :], theta[None, :], pt.constant(nodes.zbar), pt.constant(nodes.q),
                             pt.constant(nodes.k), plates, noise, xp=pt)
        pm.Potential("lik_tau_integrated", pt.logsumexp(lp + pt.constant(nodes.log_w)))
    tree = sample_model(model, draws=draws, tune=tune, chains=chains, seed=seed, progress=progress,
                        target_accept=target_accept)
    post = tree["posterior"]
    get = lambda v: np.asarray(post[v].transpose("chain", "draw", ...).values).reshape(chains * draws, -1)  # noqa: E731
    m_s = get("m")
    th_s = np.column_stack([get("l0"), get("growth")]) if noise == "growing" else get("l")
    idx = draw_tau_given(nodes, m_s, th_s, plates, noise, rng)
    step = (table.log_tau[1] - table.log_tau[0]) / SUB
    lt = np.clip(nodes.log_tau[idx] + rng.uniform(-0.5, 0.5, idx.size) * step, table.log_tau[0], table.log_tau[-1])
    out = _to_named(np.exp(lt), m_s, th_s, nodes.a[idx], nodes.h[idx], plates, noise)
    sample_stats = stats_of(tree)
    return {k_: v.reshape((chains, draws) + v.shape[1:]) for k_, v in out.items()}, sample_stats


def _log_prob(theta: np.ndarray, table, plates, log_w, noise, growth_max) -> np.ndarray:
    """log density for walkers ``theta (ndarray[w, 1 + C + k])`` = (ln τ, m, spreads)."""
    C = plates.steps_mm.size
    lt, m, th = theta[:, 0], theta[:, 1:1 + C], theta[:, 1 + C:]
    lo, hi = table.log_tau[0], table.log_tau[-1]
    ok = (lt >= lo) & (lt <= hi)
    if noise == "growing":
        ok &= np.abs(th[:, 1]) <= growth_max
    out = np.full(theta.shape[0], -np.inf)
    if ok.any():
        step = table.log_tau[1] - table.log_tau[0]
        cell = np.clip(np.rint((lt[ok] - lo) / step).astype(int), 0, table.log_tau.size - 1)
        st = node_stats(table, plates, lt[ok], log_w[cell] - np.log(step), noise, growth_max)
        out[ok] = st.log_w + log_conditional(m[ok], th[ok], st.zbar, st.q, st.k, plates, noise)
    return np.where(np.isfinite(out), out, -np.inf)


def sample_emcee(table: PeakTable, plates: Plates, pri: Priors, noise: str, log_w: np.ndarray, *, walkers: int,
                 steps: int | None, rng: np.random.Generator, progress: bool | None):
    """emcee (stretch move, vectorised) from exact draws; runs until 50 autocorrelation
    times (or exactly ``steps``). Returns (draws, sample_stats, notes) with walkers as chains."""
    import emcee

    from feeler.calib.emcee_run import run_until_converged

    _reference_only(pri)
    C = plates.steps_mm.size
    lt0, m0, th0 = _start(table, plates, pri, noise, log_w, walkers, rng)
    p0 = np.column_stack([lt0, m0, th0])
    sampler = emcee.EnsembleSampler(walkers, p0.shape[1], _log_prob, vectorize=True,
                                    args=(table, plates, log_w, noise, pri.growth_max))
    sampler.random_state = np.random.RandomState(int(rng.integers(2 ** 31))).get_state()  # legacy RNG
    burn, notes, thin = run_until_converged(sampler, p0, steps=steps, progress=progress)
    chain = np.swapaxes(sampler.get_chain(discard=burn, thin=thin), 0, 1)        # (walker, step, dim)
    W, S = chain.shape[:2]
    flat = chain.reshape(W * S, -1)
    lt = flat[:, 0]
    st = node_stats(table, plates, lt, np.zeros(lt.size), noise, pri.growth_max)
    out = _to_named(np.exp(lt), flat[:, 1:1 + C], flat[:, 1 + C:], st.a, st.h, plates, noise)
    lp = sampler.get_log_prob(discard=burn, thin=thin).T
    return {k: v.reshape((W, S) + v.shape[1:]) for k, v in out.items()}, {"lp": lp}, notes
