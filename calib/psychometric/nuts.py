"""PyMC NUTS backend of M4: hierarchical (default) or separate per-subject priors.

Hierarchical: per condition c, PSE_sc = μ_c + s_c·z_sc and log σ_sc = m_c + r_c·y_sc
(non-centred, z, y ~ N(0, 1)), so subjects' PSE and log σ are drawn from population
normals; the pooled estimate ``all`` is the population (μ_c, exp m_c, mean lapse).
Separate: independent priors per subject, and ``all`` is an extra observer fitted to
every trial at once (independent of the others in the same joint model, which is the
same as fitting it alone). The likelihood is evaluated in log space with PyMC's
``normal_lcdf``/``normal_lccdf`` (erfcx in the tails).
"""
from __future__ import annotations

import numpy as np

from feeler.calib.psychometric.cells import Cells, Priors
from feeler.models.psychometric import LAPSE_MAX

__all__ = ["nuts_fit"]


def _build(cells: Cells, priors: Priors, *, hierarchical: bool, overdispersion: bool):
    import pymc as pm
    import pytensor.tensor as pt
    from pymc.distributions.dist_math import betaln, binomln, normal_lccdf, normal_lcdf

    n_sub, n_cond = len(cells.subjects), len(cells.conditions)
    std = cells.standard_um
    with pm.Model() as model:
        if hierarchical:
            mu_pse = pm.Normal("mu_pse", std, priors.pse_sd_um, shape=n_cond)
            sd_pse = pm.HalfNormal("sd_pse", priors.pse_spread_um, shape=n_cond)
            mu_ls = pm.Normal("mu_log_sigma", priors.log_sigma_mean, priors.log_sigma_sd, shape=n_cond)
            sd_ls = pm.HalfNormal("sd_log_sigma", priors.log_sigma_spread, shape=n_cond)
            z = pm.Normal("z_pse", 0.0, 1.0, shape=(n_sub, n_cond))
            y = pm.Normal("z_log_sigma", 0.0, 1.0, shape=(n_sub, n_cond))
            pse = pm.Deterministic("pse", mu_pse + sd_pse * z)
            sigma = pm.Deterministic("sigma", pt.exp(mu_ls + sd_ls * y))
        else:
            pse = pm.Normal("pse", std, priors.pse_sd_um, shape=(n_sub, n_cond))
            log_sigma = pm.Normal("log_sigma", priors.log_sigma_mean, priors.log_sigma_sd,
                                  shape=(n_sub, n_cond))
            sigma = pm.Deterministic("sigma", pt.exp(log_sigma))
        b = pm.Beta("lapse_b", priors.lapse_a, priors.lapse_b, shape=n_sub)
        lapse = pm.Deterministic("lapse", LAPSE_MAX * b)
        s, c = cells.subject, cells.condition
        zc = (cells.x_um - pse[s, c]) / sigma[s, c]
        log_guess, log_keep = pt.log(lapse[s] / 2.0), pt.log1p(-lapse[s])
        log_p = pt.logaddexp(log_guess, log_keep + normal_lcdf(0.0, 1.0, zc))
        log_q = pt.logaddexp(log_guess, log_keep + normal_lccdf(0.0, 1.0, zc))
        n, k = cells.n, cells.k
        if overdispersion:
            log_phi = pm.Normal("log_phi", priors.log_phi_mean, priors.log_phi_sd)
            phi = pm.Deterministic("phi", pt.exp(log_phi))
            a_ = pt.maximum(phi * pt.exp(log_p), 1e-300)
            b_ = pt.maximum(phi * pt.exp(log_q), 1e-300)
            ll = binomln(n, k) + betaln(k + a_, n - k + b_) - betaln(a_, b_)
        else:
            ll = binomln(n, k) + k * log_p + (n - k) * log_q
        pm.Potential("loglik", pt.sum(ll))
    return model


def nuts_fit(cells: Cells, priors: Priors, *, hierarchical: bool, overdispersion: bool,
             rng: np.random.Generator, chains: int, draws: int, tune: int,
             target_accept: float = 0.99, progressbar: bool = False) -> tuple[dict, dict]:
    """Sample M4 with NUTS.

    Returns:
        (draws, sample_stats): ``draws`` has ``pse``, ``sigma`` (chain, draw, subject,
        condition), ``lapse`` (chain, draw, subject), ``pse_all``, ``sigma_all``
        (chain, draw, condition), ``lapse_all`` (chain, draw), the hyper-parameters
        of the hierarchical model and ``phi``; ``sample_stats`` has ``diverging``.
    """
    from feeler.calib.nuts import sample_model, stats_of

    fit_cells = cells if hierarchical else _with_pooled(cells)
    model = _build(fit_cells, priors, hierarchical=hierarchical, overdispersion=overdispersion)
    seed = int(rng.integers(2**31 - 1))
    idata = sample_model(model, draws=draws, tune=tune, chains=chains, seed=seed,
                         target_accept=target_accept, progress=progressbar, adaptation="draw_diag")
    post = idata["posterior"]

    def get(name):
        return np.asarray(post[name].values, dtype=float)

    out = {"pse": get("pse"), "sigma": get("sigma"), "lapse": get("lapse")}
    if hierarchical:
        for name in ("mu_pse", "sd_pse", "mu_log_sigma", "sd_log_sigma"):
            out[name] = get(name)
        out |= {"pse_all": out["mu_pse"], "sigma_all": np.exp(out["mu_log_sigma"]),
                "lapse_all": out["lapse"].mean(axis=-1)}
    else:
        out |= {"pse_all": out["pse"][:, :, -1], "sigma_all": out["sigma"][:, :, -1],
                "lapse_all": out["lapse"][:, :, -1]}
        for name in ("pse", "sigma", "lapse"):
            out[name] = out[name][:, :, :-1]
    if overdispersion:
        out["phi"] = get("phi")
    stats = stats_of(idata, ("diverging",))
    return out, stats


def _with_pooled(cells: Cells) -> Cells:
    """``cells`` plus a copy of every cell assigned to an extra last subject (pooled)."""
    pooled = cells.pooled()
    n_sub = len(cells.subjects)
    return Cells(cells.subjects + pooled.subjects, cells.conditions,
                 np.concatenate([cells.subject, pooled.subject + n_sub]),
                 np.concatenate([cells.condition, cells.condition]),
                 np.concatenate([cells.x_um, cells.x_um]), np.concatenate([cells.n, cells.n]),
                 np.concatenate([cells.k, cells.k]))

