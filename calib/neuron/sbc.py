"""M2 as an SBC problem: prior draws of (a, τ, h, σ), labels from the model on real scans.

The covariates are the scans of a robot-scan scene (default four-plates); the priors are
fixed before any label is seen (:func:`fixed_priors`: a centred on the nominal label scale
``scale_mm`` over the largest peak), so the simulator draws exactly from the prior the fit
uses. The fit is the default grid backend (independent draws).
"""
from __future__ import annotations

from functools import partial

import numpy as np

from feeler.calib.neuron.grid import sample_grid
from feeler.calib.neuron.model import PeakTable, Priors
from feeler.calib.neuron.synth import FOUR_PLATES, Truth, scene_scans, simulate_labels

__all__ = ["neuron_sbc_problem", "fixed_priors", "simulate_neuron", "fit_neuron_draws"]


def fixed_priors(table: PeakTable, *, scale_mm: float = 0.2, log_a_sd: float = 1.0) -> Priors:
    """Label-free priors: ln a ~ N(ln(scale/max P(τ_mid)), log_a_sd), h, σ ~ HalfNormal(scale/4)."""
    p_max = float(np.max(table.peak[:, len(table.log_tau) // 2]))
    return Priors(tau_lo_s=float(np.exp(table.log_tau[0])), tau_hi_s=float(np.exp(table.log_tau[-1])),
                  log_a_mu=float(np.log(scale_mm / p_max)), log_a_sd=log_a_sd,
                  h_scale_mm=scale_mm / 4, sigma_scale_mm=scale_mm / 4)


def simulate_neuron(rng: np.random.Generator, *, table: PeakTable, priors: Priors):
    """One (truth, labels) pair from the prior predictive."""
    p = priors
    truth = Truth(a=float(np.exp(p.log_a_mu + p.log_a_sd * rng.standard_normal())),
                  tau_s=float(np.exp(rng.uniform(np.log(p.tau_lo_s), np.log(p.tau_hi_s)))),
                  h=float(abs(p.h_scale_mm * rng.standard_normal())),
                  sigma_mm=float(abs(p.sigma_scale_mm * rng.standard_normal())))
    labels = simulate_labels(table, truth, rng)
    return {"a": truth.a, "tau_s": truth.tau_s, "h": truth.h, "sigma_mm": truth.sigma_mm}, labels


def fit_neuron_draws(labels, rng: np.random.Generator, *, table: PeakTable, priors: Priors,
                     n_draws: int = 999, tau_size: int = 160) -> dict:
    """Independent grid-posterior draws ``name -> ndarray[n_draws]``."""
    draws = sample_grid(table, labels, priors, chains=1, draws=n_draws, rng=rng, tau_size=tau_size)
    return {k: np.ravel(v) for k, v in draws.items()}


def neuron_sbc_problem(scene_path=FOUR_PLATES, *, n_grid: int = 128, tau_size: int = 160):
    """``(simulate, fit)`` for :func:`feeler.calib.sbc.run_sbc`, picklable (``tau_size``: grid
    points on the τ axis of the fit; fewer is faster and slightly coarser)."""
    data = scene_scans(scene_path)[2]
    table = data.table(n_grid=n_grid)
    priors = fixed_priors(table)
    return (partial(simulate_neuron, table=table, priors=priors),
            partial(fit_neuron_draws, table=table, priors=priors, tau_size=tau_size))
