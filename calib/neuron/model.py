"""M2 model: δ_k ~ Normal(max(a·P_k(τ) − h, 0), σ) over labelled plate scans.

P_k(τ) is the peak of the unit-gain window sum u₁ of scan k (strain = U_y / length).
It is tabulated once on a uniform grid in log τ (one :func:`peak_window_sum` per grid
point) and interpolated linearly in log τ: the fractional window makes P continuous in
τ, so every backend (grid, NUTS, emcee) sees the same continuous likelihood.

Units: δ and σ in mm (the label is the plate's step), h in mm (the decoded height is the
pulse density), a in mm per unit strain, τ in s. Priors are scaled to the data by
``delta_scale_mm`` = the largest |label| (see :class:`Priors`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feeler.errors import ArgumentError

__all__ = ["PeakTable", "Priors", "peak_table", "make_priors", "log_prior", "log_likelihood",
           "mean_mm", "PARAMS"]

PARAMS = ("a", "tau_s", "h", "sigma_mm")


@dataclass(frozen=True)
class PeakTable:
    """Peak u₁ per scan on a uniform log-τ grid.

    Attributes:
        log_tau (ndarray[n_grid]): ln τ grid (τ in s), uniform.
        peak (ndarray[n_scans, n_grid]): peak u₁ (strain units) per scan and grid τ.
    """
    log_tau: np.ndarray
    peak: np.ndarray

    def at(self, tau_s) -> np.ndarray:
        """P(τ) by linear interpolation in ln τ; ``tau_s`` ndarray[...] → ndarray[..., n_scans]."""
        x = np.log(np.asarray(tau_s, dtype=float))
        lt = self.log_tau
        step = lt[1] - lt[0]
        pos = np.clip((x - lt[0]) / step, 0.0, len(lt) - 1.0)
        i = np.minimum(np.floor(pos).astype(int), len(lt) - 2)
        w = (pos - i)[..., None]
        return self.peak.T[i] * (1.0 - w) + self.peak.T[i + 1] * w


def peak_table(strain, t_s, *, tau_lo_s: float, tau_hi_s: float, n_grid: int = 256,
               kernel: str = "boxcar") -> PeakTable:
    """Tabulate peak u₁ of ``strain (ndarray[n_scans, n_time])`` on ``n_grid`` log-spaced τ.

    ``t_s`` is ndarray[n_time] (one time base) or ndarray[n_scans, n_time] (each scan's
    own sample times, as an acquisition records them)."""
    from feeler.models import neuron

    if not (0 < tau_lo_s < tau_hi_s):
        raise ArgumentError("tau range", (tau_lo_s, tau_hi_s), "0 < tau_lo_s < tau_hi_s")
    log_tau = np.linspace(np.log(tau_lo_s), np.log(tau_hi_s), int(n_grid))

    def peaks(s, t):
        return np.stack([neuron.peak_window_sum(s, t, tau=float(np.exp(x)), kernel=kernel)
                         for x in log_tau], axis=-1)

    strain = np.asarray(strain, dtype=float)
    t_s = np.asarray(t_s, dtype=float)
    peak = peaks(strain, t_s) if t_s.ndim == 1 else \
        neuron.per_time_base(peaks, np.atleast_2d(strain), t_s)
    return PeakTable(log_tau=log_tau, peak=np.atleast_2d(peak))


@dataclass(frozen=True)
class Priors:
    """Priors of M2 (stated in every output).

    Attributes:
        tau_lo_s, tau_hi_s (float): ln τ ~ Uniform(ln tau_lo_s, ln tau_hi_s), s.
        log_a_mu, log_a_sd (float): ln a ~ Normal(log_a_mu, log_a_sd), a in mm/strain.
        h_scale_mm (float): h ~ HalfNormal(h_scale_mm), mm.
        sigma_scale_mm (float): σ ~ HalfNormal(sigma_scale_mm), mm.
    """
    tau_lo_s: float
    tau_hi_s: float
    log_a_mu: float
    log_a_sd: float
    h_scale_mm: float
    sigma_scale_mm: float

    def as_text(self) -> dict[str, str]:
        return {"a": f"ln a ~ Normal({self.log_a_mu:.4g}, {self.log_a_sd:.4g}), a in mm per unit strain",
                "tau_s": f"ln tau ~ Uniform(ln {self.tau_lo_s:.4g} s, ln {self.tau_hi_s:.4g} s)",
                "h": f"h ~ HalfNormal({self.h_scale_mm:.4g} mm)",
                "sigma_mm": f"sigma ~ HalfNormal({self.sigma_scale_mm:.4g} mm)"}

    def bounds(self) -> dict[str, tuple[float, float]]:
        """Hard prior bounds (for the piling check)."""
        return {"tau_s": (self.tau_lo_s, self.tau_hi_s)}


def make_priors(table: PeakTable, delta_mm, *, log_a_sd: float = 1.5) -> Priors:
    """Weakly informative priors scaled to the data: a centred where the largest peak
    (at the geometric-mean τ) decodes to the largest label; h, σ on the label scale."""
    d = np.asarray(delta_mm, dtype=float)
    scale = float(np.max(np.abs(d)))
    if not np.isfinite(scale) or scale <= 0:
        raise ArgumentError("labels step_mm", scale, "at least one non-zero finite step")
    mid = table.peak[:, len(table.log_tau) // 2]
    p_max = float(np.max(mid))
    if not p_max > 0:
        raise ArgumentError("scans", "peak window sum 0", "scans with some strain change")
    return Priors(tau_lo_s=float(np.exp(table.log_tau[0])), tau_hi_s=float(np.exp(table.log_tau[-1])),
                  log_a_mu=float(np.log(scale / p_max)), log_a_sd=float(log_a_sd),
                  h_scale_mm=scale, sigma_scale_mm=scale)


def mean_mm(table: PeakTable, a, tau_s, h) -> np.ndarray:
    """max(a·P(τ) − h, 0) per scan, broadcasting draws: ndarray[..., n_scans] in mm."""
    a, h = np.asarray(a, float)[..., None], np.asarray(h, float)[..., None]
    return np.maximum(a * table.at(tau_s) - h, 0.0)


def log_prior(pri: Priors, log_a, log_tau, h, log_sigma) -> np.ndarray:
    """log density in the unconstrained coordinates (ln a, ln τ, h, ln σ); −inf outside.

    Each term is computed on its own argument and the four are added by broadcasting,
    so a product grid costs one addition per cell."""
    log_a, log_tau, h, log_sigma = (np.asarray(v, float) for v in (log_a, log_tau, h, log_sigma))
    t_a = -0.5 * ((log_a - pri.log_a_mu) / pri.log_a_sd) ** 2
    inside = (log_tau >= np.log(pri.tau_lo_s)) & (log_tau <= np.log(pri.tau_hi_s))
    t_tau = np.where(inside, 0.0, -np.inf)
    t_h = np.where(h >= 0, -0.5 * (h / pri.h_scale_mm) ** 2, -np.inf)
    t_s = -0.5 * (np.exp(log_sigma) / pri.sigma_scale_mm) ** 2 + log_sigma      # Jacobian of ln σ
    return t_a + t_tau + t_h + t_s


def log_likelihood(table: PeakTable, delta_mm, a, tau_s, h, sigma_mm) -> np.ndarray:
    """Σ_k log Normal(δ_k | mean_k, σ), broadcasting draws → ndarray[...]."""
    d = np.asarray(delta_mm, float)
    sigma = np.asarray(sigma_mm, float)
    resid = d - mean_mm(table, a, tau_s, h)
    ss = np.sum(resid ** 2, axis=-1)
    n = d.shape[-1]
    return -n * np.log(sigma) - 0.5 * ss / sigma ** 2 - 0.5 * n * np.log(2 * np.pi)
