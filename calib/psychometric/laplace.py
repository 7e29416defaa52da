"""Fast deterministic M4 backend: per-subject MAP + Laplace approximation.

Each subject (and the pooled observer ``all``, every trial as one observer) is fitted
alone. Unconstrained parameters θ = (PSE_c, log σ_c for every condition c, logit B,
[log φ]) with λ = 0.5·B; the mode comes from BFGS, the covariance from the inverse of a
central-difference Hessian of the log posterior, and the draws from N(mode, H⁻¹) with
the caller's generator (independent draws, so R-hat and ESS pass naturally).

The mode is polished by Newton steps until a step moves no parameter by more than
:data:`MODE_XTOL` (relative): BFGS alone stops where the gradient is below its tolerance,
which leaves the mode uncertain at ~10⁻⁴ and lets the summation order of the likelihood
(row order, zero-trial rows, the CPU's vector width) move the result by that much. After the
polish only rounding (~10⁻¹⁰) separates such fits.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize
from scipy.special import betaln, expit

from feeler.calib.psychometric.cells import Cells, Priors, log_lik_cells
from feeler.models.psychometric import LAPSE_MAX

__all__ = ["laplace_subject", "hessian", "gradient", "newton_polish", "MODE_XTOL"]

#: relative step size under which the Newton polish of the mode stops
MODE_XTOL = 1e-10


def _unpack(theta: np.ndarray, n_cond: int, overdispersion: bool) -> dict:
    """θ (..., n_par) → pse, sigma (..., n_cond), lapse (...), phi (...) or None."""
    pse = theta[..., :n_cond]
    sigma = np.exp(theta[..., n_cond:2 * n_cond])
    lapse = LAPSE_MAX * expit(theta[..., 2 * n_cond])
    phi = np.exp(theta[..., 2 * n_cond + 1]) if overdispersion else None
    return {"pse": pse, "sigma": sigma, "lapse": lapse, "phi": phi}


def _log_post(theta, cells: Cells, priors: Priors, overdispersion: bool) -> float:
    n_cond = len(cells.conditions)
    p = _unpack(theta, n_cond, overdispersion)
    c = cells.condition
    phi = None if p["phi"] is None else np.full(c.size, p["phi"])
    ll = log_lik_cells(cells, p["pse"][c], p["sigma"][c], np.full(c.size, p["lapse"]), phi)
    lp = float(np.sum(ll))
    lp += float(np.sum(-0.5 * ((p["pse"] - cells.standard_um) / priors.pse_sd_um) ** 2))
    log_sigma = theta[n_cond:2 * n_cond]
    lp += float(np.sum(-0.5 * ((log_sigma - priors.log_sigma_mean) / priors.log_sigma_sd) ** 2))
    b = p["lapse"] / LAPSE_MAX           # Beta prior on B plus the logit Jacobian B(1 − B)
    lp += float(priors.lapse_a * np.log(b) + priors.lapse_b * np.log1p(-b)
                - betaln(priors.lapse_a, priors.lapse_b))
    if overdispersion:
        lp += float(-0.5 * ((theta[-1] - priors.log_phi_mean) / priors.log_phi_sd) ** 2)
    return lp if np.isfinite(lp) else -np.inf


def hessian(f, x: np.ndarray, step: float = 1e-4) -> np.ndarray:
    """Central-difference Hessian of a scalar function ``f`` at ``x (n,)`` → (n, n)."""
    n = x.size
    h = step * np.maximum(1.0, np.abs(x))
    out = np.empty((n, n))
    for i in range(n):
        for j in range(i, n):
            ei, ej = np.zeros(n), np.zeros(n)
            ei[i], ej[j] = h[i], h[j]
            v = (f(x + ei + ej) - f(x + ei - ej) - f(x - ei + ej) + f(x - ei - ej)) / (4 * h[i] * h[j])
            out[i, j] = out[j, i] = v
    return out


def gradient(f, x: np.ndarray, step: float = 1e-5) -> np.ndarray:
    """Central-difference gradient of a scalar function ``f`` at ``x (n,)`` → (n,)."""
    h = step * np.maximum(1.0, np.abs(x))
    out = np.empty(x.size)
    for i in range(x.size):
        e = np.zeros(x.size)
        e[i] = h[i]
        out[i] = (f(x + e) - f(x - e)) / (2 * h[i])
    return out


def newton_polish(f, x: np.ndarray, *, max_steps: int = 30) -> tuple[np.ndarray, bool]:
    """Maximise a smooth concave-near-``x`` function ``f`` by damped Newton steps.

    Returns ``(x, converged)``: converged when the last full step moved every coordinate
    by less than :data:`MODE_XTOL` · max(1, |x|). A step that does not increase ``f``
    (beyond rounding) is halved up to 30 times; a Hessian that is not negative definite
    ends the polish unconverged, at the best point so far.
    """
    fx = f(x)
    for _ in range(max_steps):
        g, h = gradient(f, x), hessian(f, x)
        try:
            np.linalg.cholesky(-0.5 * (h + h.T))
            step = np.linalg.solve(-h, g)
        except np.linalg.LinAlgError:
            return x, False
        if np.all(np.abs(step) <= MODE_XTOL * np.maximum(1.0, np.abs(x))):
            return x + step, True
        tol = 1e-12 * max(1.0, abs(fx))
        for _ in range(30):
            f_new = f(x + step)
            if f_new >= fx - tol:
                break
            step = 0.5 * step
        else:
            return x, False
        x, fx = x + step, max(f_new, fx)
    return x, False


def laplace_subject(cells: Cells, priors: Priors, *, overdispersion: bool,
                    rng: np.random.Generator, chains: int, draws: int) -> tuple[dict, list[str]]:
    """Fit one subject's cells (all conditions); returns (draws, problems).

    Returns:
        draws: dict with ``pse``, ``sigma`` (chain, draw, n_cond), ``lapse`` (chain,
        draw) and ``phi`` (chain, draw) when ``overdispersion``.
        problems: one line per optimiser or Hessian failure (empty when fine).
    """
    n_cond = len(cells.conditions)
    b0 = priors.lapse_a / (priors.lapse_a + priors.lapse_b)
    theta0 = np.concatenate([cells.standard_um, np.full(n_cond, priors.log_sigma_mean),
                             [np.log(b0 / (1 - b0))], [priors.log_phi_mean] if overdispersion else []])

    def neg(theta):
        return -_log_post(theta, cells, priors, overdispersion)

    opt = minimize(neg, theta0, method="BFGS", jac="3-point", options={"gtol": 1e-6, "maxiter": 2000})
    label = cells.subjects[0]
    mode, polished = newton_polish(lambda t: -neg(t), opt.x)
    grad = np.linalg.norm(gradient(lambda t: -neg(t), mode))
    problems = [] if polished or grad < 1e-3 else \
        [f"subject {label}: MAP optimiser did not converge (|gradient| {grad:.2g}: {opt.message})"]
    prec = -hessian(lambda t: -neg(t), mode)
    evals, evecs = np.linalg.eigh(0.5 * (prec + prec.T))
    if not np.all(evals > 0):
        problems.append(f"subject {label}: Laplace Hessian not positive definite "
                        f"(smallest eigenvalue {evals.min():.3g}); covariance clipped")
        evals = np.maximum(evals, 1e-6)
    # cov = V diag(1/λ) Vᵀ, drawn through its Cholesky factor: unlike the eigenvectors
    # (whose signs are arbitrary and flip with rounding) it is unique, so the same
    # generator state gives the same draws whatever the likelihood's summation order
    cov = (evecs / evals) @ evecs.T
    scale = np.linalg.cholesky(0.5 * (cov + cov.T))
    eps = rng.standard_normal((chains, draws, mode.size))
    theta = mode + eps @ scale.T
    out = _unpack(theta, n_cond, overdispersion)
    return {k: v for k, v in out.items() if v is not None}, problems
