"""M2 as an SBC problem: prior draws of the plates, peaks simulated at a known window.

The design (plates and scans per plate) is a robot-scan scene's; the prior is fixed
before any simulated data are seen: a proper conjugate plate prior centred on the scene's
own plate means and spread at the scene's window τ (:func:`sbc_priors`), so the
simulator draws exactly from the prior the fit uses. The window is known (the τ weights
are a model-averaging device over decoders, not a parameter with a likelihood — see
:mod:`.model`), so the fit reads the simulated peaks at that window and draws the plate
parameters with the exact backend. Ranks are checked for every plate mean and sd, the
growth of the spread (``growing``), the snap share and offsets (two-mode models: the
touches' modes are drawn with the rest), and for the derived line (a, h), the decoded-height
means and sds and ``sigma_mm`` (functions of the parameters are rank-uniform too).
"""
from __future__ import annotations

import dataclasses
from functools import partial

import numpy as np

from feeler.calib.neuron.grid import named_draws, sample_grid
from feeler.calib.neuron.model import PlatePrior, Plates, Priors, plate_stats
from feeler.calib.neuron.modes import Cells, snap_flags, within_noise
from feeler.calib.neuron.synth import FOUR_PLATES, Truth, scene_scans, simulate_peaks, single_window_table

__all__ = ["neuron_sbc_problem", "sbc_priors", "simulate_neuron", "simulate_two_mode", "fit_neuron_draws"]


def sbc_priors(peaks: np.ndarray, plates: Plates, tau_s: float, *, nu0: float = 6.0, kappa0: float = 1.0,
               growth_max: float = 1.5) -> Priors:
    """Proper plate prior from the scene's own peaks at ``tau_s``: m0 = plate means,
    s0² = pooled within-plate variance, ν₀ = ``nu0``, κ₀ = ``kappa0``."""
    mean, ss = plate_stats(np.asarray(peaks, float), plates)
    s0_sq = float(np.sum(ss) / max(plates.counts.sum() - plates.steps_mm.size, 1))
    return Priors(tau_lo_s=tau_s * (1 - 1e-6), tau_hi_s=tau_s * (1 + 1e-6), growth_max=growth_max,
                  plate=PlatePrior(nu0=nu0, s0_sq=s0_sq, kappa0=kappa0, m0=tuple(float(v) for v in mean)))


def _named_truth(mu, sigma, growth, plates, noise, tau_s) -> dict:
    out = named_draws(np.array([tau_s]), mu[None], sigma[None], np.array([growth]), plates, noise)
    flat = {}
    for k, v in out.items():
        if k == "tau_s":
            continue
        v = np.asarray(v)[0]
        if np.ndim(v):
            flat.update({f"{k}[{c}]": float(x) for c, x in enumerate(v)})
        else:
            flat[k] = float(v)
    return flat


def simulate_neuron(rng: np.random.Generator, *, plates: Plates, priors: Priors, noise: str, tau_s: float):
    """One (truth, peaks) pair from the prior predictive."""
    p = priors.plate
    C = plates.steps_mm.size
    growth = float(rng.uniform(-priors.growth_max, priors.growth_max)) if noise == "growing" else 0.0
    if noise == "per-plate":
        sigma = np.sqrt(p.nu0 * p.s0_sq / rng.chisquare(p.nu0, size=C))
    else:
        sigma = np.sqrt(p.nu0 * p.s0_sq / rng.chisquare(p.nu0)) * np.exp(growth * plates.x)
    mu = np.asarray(p.m0, float) + sigma / np.sqrt(p.kappa0) * rng.standard_normal(C)
    peaks = simulate_peaks(plates, Truth(mu=mu, sigma=sigma), rng)
    return _named_truth(mu, sigma, growth, plates, noise, tau_s), peaks


def simulate_two_mode(rng: np.random.Generator, *, plates: Plates, priors: Priors, noise: str, tau_s: float):
    """One (truth, (peaks, snap flags)) pair from the prior predictive of a two-mode model:
    π ~ Beta(1, 1); each touch of a plate with a riser snaps with probability π; σ (and
    the growth) as the one-mode model's, drawn for the ride cells and the snap cells apart
    when the touches give each mode a spread curve of its own (as the fit does:
    :attr:`~feeler.calib.neuron.modes.Cells.own_spreads`); each (plate, mode) cell's mean
    ~ Normal(m0, σ²/κ₀) (``priors.plate.m0``: 2C values, ride then snap per plate). A mode
    no touch of a plate shows has no mean of its own: the model reads that plate by its
    one mode, in the truth as in the fit (:class:`~feeler.calib.neuron.modes.Cells`)."""
    p = priors.plate
    within = within_noise(noise)
    share = float(rng.beta(1.0, 1.0))
    snap = (rng.random(plates.group.size) < share) & (plates.steps_mm[plates.group] > 0)
    cells = Cells(Plates.of(plates.steps_mm[plates.group], snap), snap)
    groups = ([cells.of_mode(k)[::2] for k in (0, 1)] if cells.own_spreads
              else [(np.arange(cells.size), cells.as_plates)])
    cell_sd, growth = np.empty(cells.size), []
    for keep, sub in groups:
        g = float(rng.uniform(-priors.growth_max, priors.growth_max)) if within == "growing" else 0.0
        cell_sd[keep] = np.sqrt(p.nu0 * p.s0_sq / rng.chisquare(p.nu0)) * np.exp(g * sub.x)
        growth.append(g)
    mu = np.asarray(p.m0, float)[cells.present] + cell_sd / np.sqrt(p.kappa0) * rng.standard_normal(cells.size)
    g_cell = cells.as_plates.group
    peaks = mu[g_cell] + cell_sd[g_cell] * rng.standard_normal(g_cell.size)
    ride, snapped = mu[cells.index[:, 0]], mu[cells.index[:, 1]]
    s_ride, s_snap = cell_sd[cells.index[:, 0]], cell_sd[cells.index[:, 1]]
    gap = snapped - ride
    sd = np.sqrt((1 - share) * s_ride ** 2 + share * s_snap ** 2 + share * (1 - share) * gap ** 2)
    truth = _named_truth(ride + share * gap, sd, growth[0], plates, "growing" if within == "growing" else noise, tau_s)
    a = truth["a"]
    for name, v in (("plate_snap_mm", gap), ("plate_ride_sd_mm", s_ride), ("plate_snap_sd_mm", s_snap)):
        truth.update({f"{name}[{c}]": float(a * x) for c, x in enumerate(v)})
    truth["snap_share"] = share
    if within == "growing":
        truth["snap_growth"] = growth[-1]
    return truth, (peaks, snap)


def fit_neuron_draws(peaks, rng: np.random.Generator, *, plates: Plates, priors: Priors, noise: str, tau_s: float,
                     n_draws: int = 999) -> dict:
    """Independent exact draws ``name -> ndarray[n_draws]`` at the known window (``peaks``
    a pair (peaks, snap flags) for a two-mode model)."""
    if within_noise(noise):
        peaks, snap = peaks
        plates = Plates.of(plates.steps_mm[plates.group], snap)
    table = single_window_table(peaks, tau_s)
    post = sample_grid(table, plates, priors, noise, np.zeros(2), chains=1, draws=n_draws, rng=rng)
    out = {}
    for k, v in post.items():
        v = np.asarray(v).reshape(n_draws, -1)
        if k == "tau_s":
            continue
        if v.shape[1] > 1 or k.startswith("plate_"):
            out.update({f"{k}[{c}]": v[:, c] for c in range(v.shape[1])})
        else:
            out[k] = v[:, 0]
    return out


def neuron_sbc_problem(scene_path=FOUR_PLATES, *, noise: str = "growing", per_plate: int | None = None):
    """``(simulate, fit)`` for :func:`feeler.calib.sbc.run_sbc`, picklable: the design of
    ``scene_path`` (optionally ``per_plate`` scans per plate) at the scene's neuron τ."""
    from feeler.models import neuron

    scene, _, data = scene_scans(scene_path, per_plate=per_plate)
    tau = float(scene.neuron.tau_s)
    plates = Plates.of(data.step_mm)
    peaks = neuron.peak_window_sum(data.strain, data.t_s, tau=tau, kernel=data.kernel)
    priors = sbc_priors(peaks, plates, tau)
    if within_noise(noise):             # m0 per (plate, mode): the scene's own cell means (a missing mode: the other's)
        cells = Cells(plates, snap_flags(data.strain, data.step_mm))
        mean, _ = plate_stats(peaks, cells.as_plates)
        priors = dataclasses.replace(priors, plate=dataclasses.replace(
            priors.plate, m0=tuple(float(v) for v in mean[cells.index].reshape(-1))))
    kw = dict(plates=plates, priors=priors, noise=noise, tau_s=tau)
    simulate = simulate_two_mode if within_noise(noise) else simulate_neuron
    return partial(simulate, **kw), partial(fit_neuron_draws, **kw)
