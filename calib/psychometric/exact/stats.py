"""Summaries and draws of an exact-grid posterior (:mod:`feeler.calib.psychometric.exact.grid`), by quadrature.

For a condition's masses w[l, f, s, m] (φ summed out, as no summary depends on it):

- location m: the m-marginal's smooth distribution function;
- threshold at P = pc, t = m + σ·q(λ): F(t) = Σ_{l,s} w[l, s]·F_{m|l,s}(t − e^s·q(λ_l));
- σ, DT = σ·q₇₅(λ) and slope = A(λ)·e^(−s) are monotone in s at each lapse node:
  F(t) = Σ_l w[l]·F_{s|l}(…);
- means are node sums Σ w·g (the trapezoid rule, spectrally accurate on these smooth,
  decaying integrands).

Rows (lapse nodes, or (lapse, s) pairs) holding less than :data:`PRUNE` of the mass are
left out of the distribution functions; the many (lapse, s) rows of the threshold are
refined 4× instead of 8× (the sum over rows smooths their error). Lapse nodes where P never reaches pc count as
"unreached" (threshold +inf): the mean of such a threshold is NaN (unless the unreached
mass is below :data:`NEGLIGIBLE`) and its quantiles above 1 − unreached are +inf.
"""
from __future__ import annotations

import numpy as np
from scipy.special import expit

from feeler.calib.psychometric.exact.grid import ObserverGrid
from feeler.calib.psychometric.exact.quadrature import FineCdf, logsumexp, quantiles
from feeler.models.psychometric import LAPSE_MAX

__all__ = ["grid_row_stats", "grid_draws", "PROBS", "PRUNE"]

PROBS = (0.025, 0.5, 0.975)
PRUNE = 1e-12
NEGLIGIBLE = 1e-4   # unreached mass up to this: the mean is over the reached mass


def _summary(mean: float, q: np.ndarray) -> dict:
    return {"mean": float(mean), "lb": float(q[0]), "median": float(q[1]), "ub": float(q[2])}


class _SRows:
    """F_{s|l} for the lapse nodes with mass: the cdf of monotone functions of s."""

    def __init__(self, s: np.ndarray, lm_ls: np.ndarray, w_l: np.ndarray):
        self.keep = w_l > PRUNE * w_l.sum()
        self.s, self.w, self.lm = s, w_l[self.keep], lm_ls[self.keep]
        self.rows = FineCdf(s, self.lm)

    def stats(self, log_shift: np.ndarray, valid: np.ndarray, increasing: bool, mean: float) -> dict:
        """Quantity g = exp(s + shift_l) (increasing) or exp(shift_l − s), over ``valid`` l."""
        ok = valid[self.keep]
        if not ok.any():
            return _summary(np.nan, np.full(3, np.inf))
        shift, w = log_shift[self.keep][ok], self.w[ok]
        rows = self.rows if ok.all() else FineCdf(self.s, self.lm[ok])

        def cdf(y):                      # of ln g: the quantiles searched in log space, where the
            y = y[None, :]               # grid is uniform (σ's spans 10⁻³-10⁶ µm: searched linearly, the
            f = rows(y - shift[:, None] if increasing else shift[:, None] - y)     # 3 rounds left 19 µm
            return w @ (f if increasing else 1.0 - f)                              # brackets)
        ends = shift[:, None] + (self.s[[0, -1]] if increasing else -self.s[[0, -1]])
        return _summary(mean, np.exp(quantiles(cdf, PROBS, ends.min() - 1e-3, ends.max() + 1e-3)))


def grid_row_stats(grid: ObserverGrid, c: int, pc: float) -> dict[str, dict]:
    """Mean, median and 95 % bounds of pse, sigma, dt, threshold, slope, lapse for
    condition ``c``; ``threshold`` and ``slope`` also have ``unreached`` (posterior mass)."""
    task, ax = grid.obs.cells.task, grid.axes[c]
    lm = logsumexp(grid.log_mass[c], axis=1)                  # (L, S, M)
    w3 = np.exp(lm)
    w_ls, w_l = w3.sum(axis=2), w3.sum(axis=(1, 2))
    lam, sig, m = LAPSE_MAX * expit(ax["l"]), np.exp(ax["s"]), ax["m"]
    out = {}
    m_cdf = FineCdf(m, logsumexp(lm, axis=(0, 1))[None])
    out["pse"] = _summary(w3.sum(axis=(0, 1)) @ m, quantiles(lambda t: m_cdf(t[None])[0], PROBS, m[0], m[-1]))

    srows = _SRows(ax["s"], logsumexp(lm, axis=2), w_l)
    every = np.ones(lam.size, bool)
    out["sigma"] = srows.stats(np.zeros(lam.size), every, True, w_ls.sum(axis=0) @ sig)
    if task.is_nafc:
        out["dt"] = _summary(np.nan, np.full(3, np.nan))
    else:
        c75 = task.z_at(0.75, lam)
        out["dt"] = srows.stats(np.log(c75), every, True, np.sum(w_ls * sig[None, :] * c75[:, None]))

    q = task.z_at(pc, lam)
    ok = np.isfinite(q)
    unreached = float(w_l[~ok].sum())
    q0 = np.where(ok, q, 0.0)
    out["threshold"] = _threshold(lm, w3, m, sig, q0, ok, unreached)
    _, scale, _ = task.base_scale_rest(lam)
    amp = scale * np.exp(-0.5 * q0 ** 2) / np.sqrt(2 * np.pi)
    mean = np.sum(w_ls[ok] * amp[ok, None] / sig[None, :]) / (1 - unreached) if unreached <= NEGLIGIBLE else np.nan
    out["slope"] = srows.stats(np.log(amp), ok, False, mean) | {"unreached": unreached}

    l_cdf = FineCdf(ax["l"], np.log(np.maximum(w_l, 1e-300))[None])
    lq = LAPSE_MAX * expit(quantiles(lambda t: l_cdf(t[None])[0], PROBS, ax["l"][0], ax["l"][-1]))
    out["lapse"] = _summary(w_l @ lam, lq)
    return out


def _threshold(lm, w3, m, sig, q, ok, unreached) -> dict:
    """Threshold t = m + σ·q(λ) (q per lapse node; ``ok`` where P reaches pc)."""
    w_ls = np.where(ok[:, None], w3.sum(axis=2), 0.0)
    keep = w_ls > PRUNE * w3.sum()
    if not keep.any():
        return _summary(np.nan, np.full(3, np.inf)) | {"unreached": unreached}
    rows = FineCdf(m, lm[keep], refine=4)                   # F_{m|l,s} over kept (l, s): many rows
    w = w_ls[keep]
    shift = (sig[None, :] * q[:, None])[keep]

    def cdf(t):
        return w @ rows(t[None, :] - shift[:, None])

    t = m[None, None, :] + (sig[None, :] * q[:, None])[:, :, None]
    mean = np.sum((w3 * ok[:, None, None]) * t) / (1 - unreached) if unreached <= NEGLIGIBLE else np.nan
    return _summary(mean, quantiles(cdf, PROBS, m[0] + shift.min(), m[-1] + shift.max())) | {"unreached": unreached}


def grid_draws(grid: ObserverGrid, rng: np.random.Generator, n: int) -> dict[str, np.ndarray]:
    """``n`` draws of pse, sigma (n, C), lapse (n, n_lapse) and phi (n,) from the grid,
    each jittered uniformly within its cell (a shared lapse/φ jittered once per draw)."""
    obs, axes = grid.obs, grid.axes
    shared_lapse = obs.lapse_per == "subject"
    w = np.exp(logsumexp(grid.log_mass[0], axis=(2, 3) if shared_lapse else (0, 2, 3)))  # (L, F) or (F,)
    flat = rng.choice(w.size, size=n, p=w.ravel() / w.sum())
    idx = np.empty((obs.n_cond, n, 4), dtype=np.intp)
    for c, lm in enumerate(grid.log_mass):
        mass = np.exp(lm)
        cond = mass.reshape(w.size, -1) if shared_lapse else np.moveaxis(mass, 1, 0).reshape(w.size, -1)
        for u in np.unique(flat):
            pick = np.flatnonzero(flat == u)
            row = cond[u] / cond[u].sum()
            j = rng.choice(row.size, size=pick.size, p=row)
            if shared_lapse:
                li, fi = np.unravel_index(np.full(pick.size, u), w.shape)
                si, mi = np.unravel_index(j, mass.shape[2:])
            else:
                fi = np.full(pick.size, u)
                li, si, mi = np.unravel_index(j, (mass.shape[0],) + mass.shape[2:])
            idx[c, pick] = np.stack([li, fi, si, mi], axis=1)

    def node(c, name, i, jitter=None):
        v = axes[c][name]
        h = v[1] - v[0] if v.size > 1 else 0.0
        return v[idx[c, :, i]] + h * (rng.uniform(-0.5, 0.5, n) if jitter is None else jitter)

    out = {"pse": np.stack([node(c, "m", 3) for c in range(obs.n_cond)], axis=-1),
           "sigma": np.exp(np.stack([node(c, "s", 2) for c in range(obs.n_cond)], axis=-1))}
    if shared_lapse:
        out["lapse"] = LAPSE_MAX * expit(node(0, "l", 0, rng.uniform(-0.5, 0.5, n)))[:, None]
    else:
        out["lapse"] = LAPSE_MAX * expit(np.stack([node(c, "l", 0) for c in range(obs.n_cond)], axis=-1))
    if obs.overdispersion:
        out["phi"] = np.exp(node(0, "f", 1, rng.uniform(-0.5, 0.5, n)))
    return out
