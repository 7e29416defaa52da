"""Fast deterministic M2 backend: the exact posterior on an adaptive 4-D grid.

Coordinates (ln τ, ln a, h, ln σ). For each (τ, a, h) cell the residual sum of squares
over the scans is computed once; σ then enters the likelihood only through it, so the σ
axis costs nothing per scan. The grid starts on the prior's bulk and is refined onto the
bounding box of every cell within ``LOG_DROP`` of the maximum (one cell of margin), until
the box is stable. Draws are independent: cells drawn by their posterior mass, jittered
uniformly inside the cell. They go through the same diagnostics as MCMC draws (R-hat ≈ 1,
bulk ESS ≈ number of draws).
"""
from __future__ import annotations

import numpy as np

from feeler.calib.neuron.model import PeakTable, Priors, log_prior

__all__ = ["sample_grid", "log_posterior_grid", "LOG_DROP"]

LOG_DROP = 25.0       # cells below max − LOG_DROP carry < e⁻²⁵ of the peak density each
_AXES = ("log_tau", "log_a", "h", "log_sigma")


def log_posterior_grid(table: PeakTable, delta_mm: np.ndarray, pri: Priors, axes: dict) -> np.ndarray:
    """Unnormalised log posterior on the product grid ``axes`` (ndarray[nτ, na, nh, nσ])."""
    lt, la, hh, ls = (np.asarray(axes[k], float) for k in _AXES)
    d = np.asarray(delta_mm, float)
    ss = np.empty((lt.size, la.size, hh.size))
    for i, p in enumerate(table.at(np.exp(lt))):                      # p: (n_scans,)
        m = np.maximum(np.exp(la)[:, None, None] * p - hh[None, :, None], 0.0)
        ss[i] = np.sum((d - m) ** 2, axis=-1)
    n = d.size
    sig2 = np.exp(2 * ls)
    ll = -n * ls - 0.5 * ss[..., None] / sig2
    lp = log_prior(pri, la[None, :, None, None], lt[:, None, None, None], hh[None, None, :, None],
                   ls[None, None, None, :])
    return ll + lp


def _start(pri: Priors) -> dict:
    return {"log_tau": (np.log(pri.tau_lo_s), np.log(pri.tau_hi_s)),
            "log_a": (pri.log_a_mu - 4 * pri.log_a_sd, pri.log_a_mu + 4 * pri.log_a_sd),
            "h": (0.0, 4 * pri.h_scale_mm),
            "log_sigma": (np.log(pri.sigma_scale_mm * 1e-4), np.log(4 * pri.sigma_scale_mm))}


def _limits(pri: Priors) -> dict:
    big = np.inf
    return {"log_tau": (np.log(pri.tau_lo_s), np.log(pri.tau_hi_s)), "log_a": (-big, big),
            "h": (0.0, big), "log_sigma": (-big, big)}


def _axes(ranges: dict, sizes: dict) -> dict:
    return {k: np.linspace(lo, hi, sizes[k]) for k, (lo, hi) in ranges.items()}


def _refine(lp: np.ndarray, axes: dict, limits: dict) -> dict:
    keep = lp >= lp.max() - LOG_DROP
    out = {}
    for dim, k in enumerate(_AXES):
        other = tuple(j for j in range(4) if j != dim)
        idx = np.flatnonzero(keep.any(axis=other))
        x = axes[k]
        step = x[1] - x[0]
        lo = max(x[idx[0]] - step, limits[k][0])
        hi = min(x[idx[-1]] + step, limits[k][1])
        out[k] = (lo, hi if hi > lo else lo + step)
    return out


# the grid misses the crest when the optimum beats its best cell by more than this (log)
CREST_GAIN = 0.5
# half-width of the box around the crest, in marginal posterior sd (Laplace)
CREST_SDS = 8.0


def _point(table: PeakTable, delta_mm, pri: Priors, v: np.ndarray) -> float:
    return float(log_posterior_grid(table, delta_mm, pri, {k: v[i:i + 1] for i, k in enumerate(_AXES)})[0, 0, 0, 0])


def _crest_box(table: PeakTable, delta_mm, pri: Priors, axes: dict, lp: np.ndarray, ranges: dict,
               limits: dict) -> dict | None:
    """A box around the posterior's crest when the grid's cells straddle it, else None.

    A large gain a pins (a, h) on a ridge narrower than the cells: every cell is then
    off the crest, its residuals too large, and σ comes out too high (seen in SBC). The
    box test of :func:`_refine` cannot see this, because the coarse maximum is itself off
    the crest. So the optimum is found continuously from the best cell; if it beats the
    best cell by more than ``CREST_GAIN``, (a, h, σ) get the box optimum ± ``CREST_SDS``
    marginal sd (Laplace, from the numerical Hessian); τ keeps its range (its posterior
    can be multimodal)."""
    from scipy.optimize import minimize

    idx = np.unravel_index(int(np.argmax(lp)), lp.shape)
    x0 = np.array([axes[k][i] for k, i in zip(_AXES, idx)])
    res = minimize(lambda v: -_point(table, delta_mm, pri, v), x0, method="Nelder-Mead",
                   options={"xatol": 1e-7, "fatol": 1e-7, "maxiter": 4000})
    if not np.isfinite(res.fun) or -res.fun <= lp.max() + CREST_GAIN:
        return None
    x = res.x
    steps = np.array([axes[k][1] - axes[k][0] for k in _AXES]) * 1e-2
    hess = np.empty((4, 4))
    f0 = _point(table, delta_mm, pri, x)
    for i in range(4):
        for j in range(i, 4):
            ei, ej = np.eye(4)[i] * steps[i], np.eye(4)[j] * steps[j]
            hess[i, j] = hess[j, i] = (_point(table, delta_mm, pri, x + ei + ej) - _point(table, delta_mm, pri, x + ei)
                                       - _point(table, delta_mm, pri, x + ej) + f0) / (steps[i] * steps[j])
    try:
        sd = np.sqrt(np.diag(np.linalg.inv(-hess)))
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(sd)) or np.any(sd <= 0):
        return None
    box = dict(ranges)
    for i, k in enumerate(_AXES):
        if k == "log_tau":
            continue
        lo, hi = max(x[i] - CREST_SDS * sd[i], limits[k][0]), min(x[i] + CREST_SDS * sd[i], limits[k][1])
        box[k] = (lo, hi)
    return box


def sample_grid(table: PeakTable, delta_mm, pri: Priors, *, chains: int, draws: int,
                rng: np.random.Generator, size: int = 40, tau_size: int = 160, passes: int = 8) -> dict:
    """Independent posterior draws ``dict[name] -> ndarray (chains, draws)`` from the grid.

    Args:
        size (int): points per axis of (a, h); σ gets 1.5× as many.
        tau_size (int): points on the τ axis. The likelihood can have fine structure in τ:
            a peak jumps each time the window takes in one more whole frame of a transient
            (see calib/neuron/mcmc.py), so τ needs a finer axis: at 40 points the τ mean
            moved by 0.3 posterior sd against a 64-point grid; at 160 it is stable.
        passes (int): maximum refinements (stops earlier once the box is stable).
    """
    sizes = {"log_tau": tau_size, "log_a": size, "h": size, "log_sigma": int(1.5 * size)}
    limits = _limits(pri)
    ranges = _start(pri)
    for _ in range(passes):
        axes = _axes(ranges, sizes)
        lp = log_posterior_grid(table, delta_mm, pri, axes)
        new = _refine(lp, axes, limits)
        widths = {k: ranges[k][1] - ranges[k][0] for k in _AXES}
        stable = all(abs(new[k][0] - ranges[k][0]) < 0.05 * widths[k]
                     and abs(new[k][1] - ranges[k][1]) < 0.05 * widths[k] for k in _AXES)
        ranges = new
        if stable:
            break
    axes = _axes(ranges, sizes)
    lp = log_posterior_grid(table, delta_mm, pri, axes)
    zoomed = _crest_box(table, delta_mm, pri, axes, lp, ranges, limits)
    if zoomed is not None:               # the grid ran beside a crest narrower than its cells
        axes = _axes(zoomed, sizes)
        lp = log_posterior_grid(table, delta_mm, pri, axes)
    w = np.exp(lp - lp.max()).ravel()
    n = chains * draws
    cells = np.unravel_index(rng.choice(w.size, size=n, p=w / w.sum()), lp.shape)
    out = {}
    for dim, k in enumerate(_AXES):
        x = axes[k]
        step = x[1] - x[0]
        v = x[cells[dim]] + rng.uniform(-0.5, 0.5, n) * step
        lo, hi = limits[k]
        v = np.where(v < lo, 2 * lo - v, v)          # reflect the jitter at hard bounds
        v = np.where(v > hi, 2 * hi - v, v)
        out[k] = v.reshape(chains, draws)
    return {"a": np.exp(out["log_a"]), "tau_s": np.exp(out["log_tau"]), "h": out["h"],
            "sigma_mm": np.exp(out["log_sigma"])}
