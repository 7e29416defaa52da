"""Exact M2 backend ("grid"): independent draws of the decoder posterior.

τ is drawn from its weights on the nodes of the peak table (:mod:`.window`), jittered
uniformly inside its cell (reflected at the prior's bounds); the scans' peaks are read at
that τ (linear in ln τ, as in every backend), and the plate parameters are drawn exactly
from their conjugate posterior at that τ (:mod:`.conjugate`; under the reference prior a
two-mode model's cell means from their posterior pooled along each mode's line,
:mod:`.pooling`). The draws go through the
same diagnostics as MCMC draws (R-hat ≈ 1, bulk ESS ≈ the number of draws).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from feeler.calib.neuron.conjugate import draw_plate_parameters
from feeler.calib.neuron.model import PeakTable, Plates, Priors, decoder_line, plate_stats
from feeler.calib.neuron.modes import Cells, own_spread_weight, within_noise
from feeler.calib.neuron.pooling import pooled_means

__all__ = ["sample_grid", "draw_tau", "named_draws", "two_mode_draws"]


def draw_tau(log_tau_nodes: np.ndarray, log_w: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` draws of τ (s): a node by its weight, jittered uniformly inside its cell."""
    w = np.exp(log_w - np.max(log_w))
    idx = rng.choice(w.size, size=n, p=w / w.sum())
    step = log_tau_nodes[1] - log_tau_nodes[0]
    x = log_tau_nodes[idx] + rng.uniform(-0.5, 0.5, n) * step
    lo, hi = log_tau_nodes[0], log_tau_nodes[-1]
    x = np.where(x < lo, 2 * lo - x, x)
    x = np.where(x > hi, 2 * hi - x, x)
    return np.exp(x)


def named_draws(tau_s: np.ndarray, mu: np.ndarray, sigma: np.ndarray, growth: np.ndarray, plates: Plates,
                noise: str) -> dict:
    """The posterior's variables from draws of τ and the plate parameters (units of P):
    a, tau_s, h, sigma_mm (ndarray[N]), plate_mean_mm, plate_sd_mm (ndarray[N, C]) and
    growth (ndarray[N], growing noise only)."""
    a, h = decoder_line(mu, plates)
    sd_mm = a[:, None] * sigma
    out = {"a": a, "tau_s": tau_s, "h": h, "sigma_mm": np.sqrt(np.mean(sd_mm ** 2, axis=1)),
           "plate_mean_mm": a[:, None] * mu - h[:, None], "plate_sd_mm": sd_mm}
    if noise == "growing":
        out["growth"] = growth
    return out


def sample_grid(table: PeakTable, plates: Plates, priors: Priors, noise: str, log_w: np.ndarray, *,
                chains: int, draws: int, rng: np.random.Generator) -> dict:
    """Independent draws ``name -> ndarray (chains, draws[, C])``.

    Args:
        log_w (ndarray[n_grid]): log weights of the table's τ nodes (:func:`.window.tau_log_weights`).
    """
    n = chains * draws
    tau = draw_tau(table.log_tau, log_w, n, rng)
    if within_noise(noise):
        out = two_mode_draws(rng, tau, table.at(tau), plates, priors, within_noise(noise))
    else:
        mean, ss = plate_stats(table.at(tau), plates)
        par = draw_plate_parameters(rng, mean, ss, plates, noise, priors.plate, priors.growth_max)
        out = named_draws(tau, par["mu"], par["sigma"], par["growth"], plates, noise)
    return {k: v.reshape((chains, draws) + v.shape[1:]) for k, v in out.items()}


def two_mode_draws(rng: np.random.Generator, tau_s: np.ndarray, peaks: np.ndarray, plates: Plates,
                   priors: Priors, within: str = "constant", *, shared_spread: bool = False,
                   pooled: bool = True) -> dict:
    """Named draws of the ``two-mode`` model from ``peaks (ndarray[S, n_scans])`` at ``tau_s``:
    each (plate, mode) cell's mean and σ exactly as the ``within`` (constant or growing)
    model's plates (:mod:`.conjugate`, the cells as plates), the snap share
    π ~ Beta(1 + snaps, 1 + rides). Under the reference prior (κ₀ = 0) the means of each
    mode's cells are pooled along a line in the step (:func:`.pooling.pooled_means`; not
    when ``pooled`` is False: the flat means). The ride cells and the snap cells each have a spread
    curve of their own (σ₀ and, growing, g) when both modes have the scans for it
    (:attr:`.modes.Cells.own_spreads`), else (or ``shared_spread``) one for both; under the
    reference prior each draw takes its own curves with the weight the cells' scatter at
    its window gives them (:func:`.modes.own_spread_weight`) and one curve otherwise.

    Named as the other models' (a plate's mean and sd are those of its mixture of modes,
    mm), plus ``plate_snap_mm`` (ndarray[N, C]: snap mean − ride mean, mm),
    ``plate_ride_sd_mm`` and ``plate_snap_sd_mm`` (ndarray[N, C]: the sd within each mode,
    mm), ``snap_share`` (ndarray[N]) and, growing, ``snap_growth`` (the snaps' g;
    ``growth`` is then the rides'; the two are equal when one curve serves both)."""
    cells = Cells(plates, plates.snap)
    mean, ss = plate_stats(peaks, cells.as_plates)
    prior = priors.plate
    if prior.kappa0 > 0:                    # a proper prior: m0 per (plate, mode), 2C of them; the cells' own
        prior = dataclasses.replace(prior, m0=tuple(np.asarray(prior.m0, float)[cells.present]))
    S = mean.shape[0]
    own = np.full(S, cells.own_spreads and not shared_spread)
    if own.any() and prior.kappa0 == 0:     # the reference prior: a curve each where the data tell them apart
        own = rng.uniform(size=S) < own_spread_weight(ss, cells, within, priors.growth_max)
    mu, sigma, growth = np.empty(mean.shape), np.empty(mean.shape), np.zeros((2, S))
    rows = np.flatnonzero(own)
    if rows.size:
        for k in (0, 1):
            keep, _, sub = cells.of_mode(k)
            pri = dataclasses.replace(prior, m0=tuple(np.asarray(prior.m0, float)[keep])) if prior.kappa0 > 0 else prior
            par = draw_plate_parameters(rng, mean[rows][:, keep], ss[rows][:, keep], sub, within, pri, priors.growth_max)
            mu[np.ix_(rows, keep)], sigma[np.ix_(rows, keep)] = par["mu"], par["sigma"]
            growth[k, rows] = par["growth"]
    rows = np.flatnonzero(~own)
    if rows.size:
        par = draw_plate_parameters(rng, mean[rows], ss[rows], cells.as_plates, within, prior, priors.growth_max)
        mu[rows], sigma[rows], growth[:, rows] = par["mu"], par["sigma"], par["growth"]
    if prior.kappa0 == 0 and pooled:        # the reference prior: each mode's means pooled along its line
        for k in (0, 1):
            keep = np.flatnonzero(cells.mode == k)
            mu[:, keep] = pooled_means(rng, mean[:, keep], sigma[:, keep], cells.as_plates.counts[keep],
                                       cells.as_plates.steps_mm[keep])
    ride, snap = mu[:, cells.index[:, 0]], mu[:, cells.index[:, 1]]
    s_ride, s_snap = sigma[:, cells.index[:, 0]], sigma[:, cells.index[:, 1]]
    share = rng.beta(1.0 + cells.snaps, 1.0 + cells.rides, size=tau_s.size)[:, None]
    gap = snap - ride
    sd = np.sqrt((1 - share) * s_ride ** 2 + share * s_snap ** 2 + share * (1 - share) * gap ** 2)
    out = named_draws(tau_s, ride + share * gap, sd, growth[0], plates,
                      "growing" if within == "growing" else "two-mode")
    a = out["a"][:, None]
    out.update(plate_snap_mm=a * gap, plate_ride_sd_mm=a * s_ride, plate_snap_sd_mm=a * s_snap, snap_share=share[:, 0])
    if within == "growing":                 # the snaps' g (the rides' when one curve serves both)
        out["snap_growth"] = growth[1]
    return out
