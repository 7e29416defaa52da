"""psignifit 4 (wichmann-lab, from the package registry) configured as feeler's M4 model,
and summaries of its posterior grid computed the same way for both packages.

Matching (read from psignifit 4.3's source):
- comparison design = psignifit "equal asymptote" with its λ = feeler's λ/2; nAFC =
  psignifit "nAFC" with γ = 1/n and its λ = feeler's λ·(1 − 1/n);
- cumulative normal: psignifit's width = σ·(Φ⁻¹(0.95) − Φ⁻¹(0.05)) (width_alpha 0.05),
  its threshold (at the unscaled ½) = feeler's PSE / location m; η (overdispersion) = 0;
- priors as densities over psignifit's linear parameters: threshold Normal, width the
  LogNormal of σ (with the 1/width Jacobian), λ the scaled Beta. psignifit's
  "equal asymptote" adds log prior(λ) twice (once for λ and once for γ = λ), so there
  its λ prior is passed as the square root of the density.

Summaries of psignifit's grid: means Σ mass·value; quantiles of the threshold from its
marginal and of derived quantities (DT, threshold at pc) from the node masses sorted by
value, both with the cumulative mass taken at the middle of each node's mass.
"""
from __future__ import annotations

import warnings

import numpy as np
from scipy.stats import beta as beta_dist
from scipy.stats import norm

__all__ = ["psignifit_fit", "grid_summary", "WIDTH_PER_SIGMA"]

WIDTH_PER_SIGMA = float(norm.ppf(0.95) - norm.ppf(0.05))


def psignifit_fit(x, n, k, resolved, c: int = 0, *, nafc: int | None = None,
                  steps: dict | None = None, max_bound_value: float = 1e-7):
    """psignifit's fit of one condition under feeler's resolved priors (``resolved``)."""
    import psignifit as ps

    x, n, k = (np.asarray(v, float) for v in (x, n, k))
    lo, hi = x.min(), x.max()
    span = hi - lo
    pm, psd = resolved.pse_mean[c], resolved.pse_sd[c]
    lm, lsd = resolved.log_sigma_mean[c], resolved.log_sigma_sd
    a, b = resolved.lapse_a, resolved.lapse_b
    keep = 0.25 if nafc is None else 0.5 * (1 - 1 / nafc)     # psignifit λ = keep · B

    def width_prior(w):
        w = np.maximum(w, 1e-300)
        return norm.pdf(np.log(w / WIDTH_PER_SIGMA), lm, lsd) / w

    def lapse_prior(lam):
        dens = beta_dist.pdf(np.clip(lam / keep, 0, 1), a, b) / keep
        return np.sqrt(dens) if nafc is None else dens

    priors = {"threshold": lambda t: norm.pdf(t, pm, psd), "width": width_prior, "lambda": lapse_prior}
    bounds = {"threshold": (lo - 1.5 * span, hi + 1.5 * span), "width": (span / 200, 10 * span),
              "lambda": (0.0, keep)}
    kind = {"experiment_type": "equal asymptote"} if nafc is None else {"experiment_type": f"{nafc}AFC"}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return ps.psignifit(np.column_stack([x, k, n]), sigmoid="norm", fixed_parameters={"eta": 0.0},
                            priors=priors, bounds=bounds, debug=True, verbose=False,
                            grid_steps=steps or {"threshold": 100, "width": 100, "lambda": 40},
                            max_bound_value=max_bound_value, **kind)


def _midpoint_quantiles(values, mass, probs=(0.025, 0.975)):
    order = np.argsort(values, kind="stable")
    v, m = values[order], mass[order]
    return np.interp(probs, np.cumsum(m) - m / 2, v)


def grid_summary(res, *, nafc: int | None = None, pc: float = 0.75) -> dict:
    """Mean, 95 % bounds and MAP of PSE (location), DT (comparison) and the threshold at
    ``pc`` from psignifit's posterior grid, in feeler's terms (µm)."""
    g = res.parameter_values
    mass = np.asarray(res.debug["posteriors"], float)
    names = sorted(g) if mass.ndim == len(g) else sorted(set(g) - {"gamma"})  # equal asymptote: γ = λ
    axes = {name: i for i, name in enumerate(names)}                # psignifit: alphabetical axes
    shape = [1] * mass.ndim

    def along(name):
        s = list(shape)
        s[axes[name]] = -1
        return np.asarray(g[name], float).reshape(s)
    mass = mass / mass.sum()
    thr, sig, lam_ps = along("threshold"), along("width") / WIDTH_PER_SIGMA, along("lambda")
    thr_marg = mass.sum(axis=tuple(i for i in range(mass.ndim) if i != axes["threshold"]))
    out = {"pse": (float((mass * thr).sum()),
                   *_midpoint_quantiles(np.asarray(g["threshold"], float), thr_marg))}
    mp = res.parameter_estimate_MAP
    gam = 0.0 if nafc is None else 1 / nafc

    def at_pc(t, s, lp, p):
        with np.errstate(invalid="ignore"):
            return t + s * norm.ppf((p - (lp if nafc is None else gam)) / (1 - gam - lp - (lp if nafc is None else 0)))
    derived = {"threshold": lambda t, s, lp: at_pc(t, s, lp, pc)}
    if nafc is None:
        derived["dt"] = lambda t, s, lp: at_pc(t, s, lp, 0.75) - t
    for name, f in derived.items():
        vals = np.broadcast_to(f(thr, sig, lam_ps), mass.shape).ravel()
        ok = np.isfinite(vals)
        out[name] = (float((mass.ravel()[ok] * vals[ok]).sum() / mass.ravel()[ok].sum()),
                     *_midpoint_quantiles(vals[ok], mass.ravel()[ok]))
        out[name + "_map"] = float(f(mp["threshold"], mp["width"] / WIDTH_PER_SIGMA, mp["lambda"]))
    out["pse_map"] = float(mp["threshold"])
    return out
