"""One observer's M4 posterior in unconstrained coordinates (shared by the deterministic
backends: the mode, Laplace and the placement of the exact grid).

θ = (m_c for every condition c, s_c = log σ_c, l = logit B (one per observer, or one per
condition with ``lapse_per="condition"``), [f = log φ]) with λ = 0.5·B. The density of θ
includes the Jacobians of the transforms (so its mode is the "Laplace" mode);
:meth:`Observer.log_natural` is the density over (m, σ, λ, φ) themselves, whose mode is
the MAP reported in the tables (psignifit's convention: the mode over linear parameters).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import betaln, expit, log_expit

from feeler.calib.psychometric.model.cells import Cells, log_lik_cells
from feeler.calib.psychometric.model.priors import Resolved
from feeler.models.psychometric import LAPSE_MAX

__all__ = ["Observer", "LAPSE_PER"]

LAPSE_PER = ("subject", "condition")


@dataclass(frozen=True)
class Observer:
    """The cells of one observer (one subject label, every condition of ``cells``)."""
    cells: Cells
    priors: Resolved
    lapse_per: str = "subject"
    overdispersion: bool = False

    @property
    def n_cond(self) -> int:
        return len(self.cells.conditions)

    @property
    def n_lapse(self) -> int:
        return self.n_cond if self.lapse_per == "condition" else 1

    @property
    def n_par(self) -> int:
        return 2 * self.n_cond + self.n_lapse + int(self.overdispersion)

    def start(self) -> np.ndarray:
        """The prior centre: a starting point for the mode search."""
        p = self.priors
        b0 = (p.lapse_a) / (p.lapse_a + p.lapse_b)
        return np.concatenate([p.pse_mean, p.log_sigma_mean, np.full(self.n_lapse, np.log(b0 / (1 - b0))),
                               [p.log_phi_mean] if self.overdispersion else []])

    def data_start(self) -> np.ndarray:
        """A start from the data alone: per condition the trial-weighted mean level and a
        quarter of the tested range (the prior centre where a condition has no trials)."""
        theta = self.start()
        cells, c_n = self.cells, self.n_cond
        for c in range(c_n):
            sel = (cells.condition == c) & (cells.n > 0)
            if not sel.any():
                continue
            x = cells.x_um[sel]
            theta[c] = float(np.average(x, weights=cells.n[sel]))
            if x.max() > x.min():
                theta[c_n + c] = float(np.log((x.max() - x.min()) / 4))
        return theta

    def unpack(self, theta: np.ndarray) -> dict:
        """θ (..., n_par) → pse, sigma (..., n_cond), lapse (..., n_lapse), phi (...) or None."""
        c = self.n_cond
        lapse = LAPSE_MAX * expit(theta[..., 2 * c:2 * c + self.n_lapse])
        return {"pse": theta[..., :c], "sigma": np.exp(theta[..., c:2 * c]), "lapse": lapse,
                "phi": np.exp(theta[..., -1]) if self.overdispersion else None}

    def log_lik(self, theta: np.ndarray) -> np.ndarray:
        """Log-likelihood at θ (..., n_par) → (...)."""
        p = self.unpack(theta)
        c = self.cells.condition
        lap = p["lapse"][..., c if self.lapse_per == "condition" else np.zeros_like(c)]
        phi = None if p["phi"] is None else p["phi"][..., None]
        return np.sum(log_lik_cells(self.cells, p["pse"][..., c], p["sigma"][..., c], lap, phi), axis=-1)

    def log_prior(self, theta: np.ndarray) -> np.ndarray:
        """Log prior density of θ up to a constant (Jacobians of log σ and logit B included)."""
        r, c = self.priors, self.n_cond
        lp = np.sum(-0.5 * ((theta[..., :c] - r.pse_mean) / r.pse_sd) ** 2, axis=-1)
        lp += np.sum(-0.5 * ((theta[..., c:2 * c] - r.log_sigma_mean) / r.log_sigma_sd) ** 2, axis=-1)
        lp += np.sum(lapse_logit_prior(theta[..., 2 * c:2 * c + self.n_lapse], r.lapse_a, r.lapse_b), axis=-1)
        if self.overdispersion:
            lp += -0.5 * ((theta[..., -1] - r.log_phi_mean) / r.log_phi_sd) ** 2
        return lp

    def log_post(self, theta: np.ndarray) -> np.ndarray:
        """Unnormalised log posterior density of θ; -inf where not finite."""
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            v = self.log_lik(theta) + self.log_prior(theta)
        return np.where(np.isfinite(v), v, -np.inf)

    def log_natural(self, theta: np.ndarray) -> np.ndarray:
        """Log posterior density over (m, σ, λ, φ) at θ: the θ density less log|Jacobian|."""
        c = self.n_cond
        l = theta[..., 2 * c:2 * c + self.n_lapse]
        jac = np.sum(theta[..., c:2 * c], axis=-1) + np.sum(log_expit(l) + log_expit(-l), axis=-1)
        if self.overdispersion:
            jac = jac + theta[..., -1]
        return self.log_post(theta) - jac


def lapse_logit_prior(l, a: float, b: float):
    """log density of l = logit B for B ~ Beta(a, b): a·log B + b·log(1 − B) − log Beta(a, b)."""
    return a * log_expit(l) + b * log_expit(-l) - betaln(a, b)
