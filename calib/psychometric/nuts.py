"""PyMC NUTS backend of M4: hierarchical (default) or separate per-subject priors.

Hierarchical: per condition c, PSE_sc = μ_c + s_c·z_sc and log σ_sc = m_c + r_c·y_sc
(non-centred, z, y ~ N(0, 1)), so subjects' PSE and log σ are drawn from population
normals; ``all`` is then either the population (μ_c, exp m_c, mean lapse) or the pooled
trials fitted as one more observer with its own independent priors (a separate block of
the same model, which is the same as fitting it alone).
Separate: independent priors per subject, and ``all`` is the pooled observer.
The likelihood of either task (:mod:`feeler.calib.psychometric.model.task`) is evaluated in log space with PyMC's
``normal_lcdf``/``normal_lccdf`` (erfcx in the tails). Lapses are per subject or per
subject and condition; φ (beta-binomial) per observer.
"""
from __future__ import annotations

import numpy as np

from feeler.calib.psychometric.model.cells import Cells
from feeler.calib.psychometric.model.priors import Resolved
from feeler.models.psychometric import LAPSE_MAX

__all__ = ["nuts_fit"]


def _block(cells: Cells, r: Resolved, *, name: str, hierarchical: bool, lapse_per: str,
           overdispersion: bool):
    """Variables and log-likelihood of the observers of ``cells`` (suffix ``name``)."""
    import pymc as pm
    import pytensor.tensor as pt
    from pymc.distributions.dist_math import betaln, binomln, normal_lccdf, normal_lcdf

    n_sub, n_cond = len(cells.subjects), len(cells.conditions)
    if hierarchical:
        mu_pse = pm.Normal("mu_pse", r.pse_mean, r.pse_sd, shape=n_cond)
        sd_pse = pm.HalfNormal("sd_pse", r.pse_spread, shape=n_cond)
        mu_ls = pm.Normal("mu_log_sigma", r.log_sigma_mean, r.log_sigma_sd, shape=n_cond)
        sd_ls = pm.HalfNormal("sd_log_sigma", r.log_sigma_spread, shape=n_cond)
        z = pm.Normal("z_pse", 0.0, 1.0, shape=(n_sub, n_cond))
        y = pm.Normal("z_log_sigma", 0.0, 1.0, shape=(n_sub, n_cond))
        pse = pm.Deterministic("pse" + name, mu_pse + sd_pse * z)
        sigma = pm.Deterministic("sigma" + name, pt.exp(mu_ls + sd_ls * y))
    else:
        pse = pm.Normal("pse" + name, r.pse_mean, r.pse_sd, shape=(n_sub, n_cond))
        log_sigma = pm.Normal("log_sigma" + name, r.log_sigma_mean, r.log_sigma_sd, shape=(n_sub, n_cond))
        sigma = pm.Deterministic("sigma" + name, pt.exp(log_sigma))
    lapse_shape = (n_sub, n_cond) if lapse_per == "condition" else (n_sub,)
    b = pm.Beta("lapse_b" + name, r.lapse_a, r.lapse_b, shape=lapse_shape)
    lapse = pm.Deterministic("lapse" + name, LAPSE_MAX * b)
    s, c = cells.subject, cells.condition
    lam = lapse[s, c] if lapse_per == "condition" else lapse[s]
    zc = (cells.x_um - pse[s, c]) / sigma[s, c]
    g = cells.task.guess
    if cells.task.is_nafc:
        log_base, log_scale, log_rest = (pt.log(g) + 0 * lam, np.log1p(-g) + pt.log1p(-lam),
                                         pt.log(lam) + np.log1p(-g))
    else:
        log_base, log_scale, log_rest = pt.log(lam / 2.0), pt.log1p(-lam), pt.log(lam / 2.0)
    log_p = pt.logaddexp(log_base, log_scale + normal_lcdf(0.0, 1.0, zc))
    log_q = pt.logaddexp(log_rest, log_scale + normal_lccdf(0.0, 1.0, zc))
    n, k = cells.n, cells.k
    if overdispersion:
        log_phi = pm.Normal("log_phi" + name, r.log_phi_mean, r.log_phi_sd, shape=n_sub)
        phi = pm.Deterministic("phi" + name, pt.exp(log_phi))
        a_ = pt.maximum(phi[s] * pt.exp(log_p), 1e-300)
        b_ = pt.maximum(phi[s] * pt.exp(log_q), 1e-300)
        return pt.sum(binomln(n, k) + betaln(k + a_, n - k + b_) - betaln(a_, b_))
    return pt.sum(binomln(n, k) + k * log_p + (n - k) * log_q)


def _build(cells: Cells, r: Resolved, *, hierarchical: bool, pooled: bool, lapse_per: str,
           overdispersion: bool):
    import pymc as pm

    kw = dict(lapse_per=lapse_per, overdispersion=overdispersion)
    with pm.Model() as model:
        ll = _block(cells, r, name="", hierarchical=hierarchical, **kw)
        if pooled:
            ll = ll + _block(cells.pooled(), r, name="_pooled", hierarchical=False, **kw)
        pm.Potential("loglik", ll)
    return model


def nuts_fit(cells: Cells, priors: Resolved, *, hierarchical: bool, pooled: bool, lapse_per: str,
             overdispersion: bool, rng: np.random.Generator, chains: int, draws: int, tune: int,
             target_accept: float = 0.99, progressbar: bool | None = False) -> tuple[dict, dict]:
    """Sample M4 with NUTS.

    Args:
        pooled (bool): add the pooled observer (every trial as one observer) as ``all``;
            False with ``hierarchical``: ``all`` is the population; False otherwise: no
            ``*_all`` draws (the caller copies its one subject).
    Returns:
        (draws, sample_stats): ``draws`` has ``pse``, ``sigma`` (chain, draw, subject,
        condition), ``lapse`` (chain, draw, subject[, condition]), ``pse_all``,
        ``sigma_all`` (chain, draw, condition), ``lapse_all`` (chain, draw[, condition]),
        the hyper-parameters of the hierarchical model and ``phi``/``phi_all``;
        ``sample_stats`` has ``diverging``.
    """
    from feeler.calib.nuts import sample_model, stats_of

    model = _build(cells, priors, hierarchical=hierarchical, pooled=pooled, lapse_per=lapse_per,
                   overdispersion=overdispersion)
    seed = int(rng.integers(2**31 - 1))
    idata = sample_model(model, draws=draws, tune=tune, chains=chains, seed=seed,
                         target_accept=target_accept, progress=progressbar, adaptation="draw_diag")
    post = idata["posterior"]

    def get(name):
        return np.asarray(post[name].values, dtype=float)

    out = {"pse": get("pse"), "sigma": get("sigma"), "lapse": get("lapse")}
    if overdispersion:
        out["phi"] = get("phi")
    if hierarchical:
        for name in ("mu_pse", "sd_pse", "mu_log_sigma", "sd_log_sigma"):
            out[name] = get(name)
    if pooled:
        out |= {"pse_all": get("pse_pooled")[:, :, 0], "sigma_all": get("sigma_pooled")[:, :, 0],
                "lapse_all": get("lapse_pooled")[:, :, 0]}
        if overdispersion:
            out["phi_all"] = get("phi_pooled")[:, :, 0]
    elif hierarchical:
        out |= {"pse_all": out["mu_pse"], "sigma_all": np.exp(out["mu_log_sigma"]),
                "lapse_all": out["lapse"].mean(axis=2)}
    stats = stats_of(idata, ("diverging",))
    return out, stats
