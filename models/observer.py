"""Observer: peak pulse densities → accepted step heights → 2AFC choice probabilities.

The paper (§4.2, Fig. 6) turns the model's peak pulse density z into an *accepted step
height* with one conversion factor: it regresses peak z on the presented step height
separately for v = 20 and 40 mm/s and adopts the mean regression coefficient. Here the
regressions go through the origin (z = b_v·δ, b_v = Σ zδ / Σ δ²), and the accepted height
is ŝ = κ·z with κ = 1 / mean_v(b_v). A 2AFC trial compares two accepted heights with
Gaussian decision noise σ_d:

    P(second judged higher) = Φ((ŝ₂ − ŝ₁)/σ_d)        (optionally with a lapse λ:
                             λ/2 + (1 − λ)·Φ(...)),

evaluated in log space (``scipy.special.log_ndtr``) so that probabilities near 0 and 1
neither underflow nor round to 1.
"""
from __future__ import annotations

import numpy as np

from feeler.errors import ArgumentError
from feeler.models.psychometric import log_lapse_ndtr

__all__ = ["conversion_factor", "accepted_height", "log_choice_prob", "choice_prob"]


def conversion_factor(peak_z, presented_um, groups=None) -> float:
    """κ (µm per unit pulse density) by regression through the origin, as in the paper.

    Args:
        peak_z (array_like[n]): peak pulse densities of simulated slides, ≥ 0.
        presented_um (array_like[n]): presented step heights (µm).
        groups (array_like[n] | None): condition of each slide (e.g. the speed in mm/s);
            one slope per group, κ = 1 / mean of the slopes. None: one group.
    Returns:
        float: κ such that ŝ = κ·peak z.
    """
    z = np.asarray(peak_z, dtype=float).ravel()
    s = np.asarray(presented_um, dtype=float).ravel()
    if z.shape != s.shape or z.size == 0:
        raise ArgumentError("peak_z", z.shape, f"must be non-empty and match presented_um {s.shape}")
    if not (np.all(np.isfinite(z)) and np.all(np.isfinite(s))):
        raise ArgumentError("peak_z", z, "peak_z and presented_um must be finite")
    g = np.zeros(z.size) if groups is None else np.asarray(groups).ravel()
    if g.shape != z.shape:
        raise ArgumentError("groups", g.shape, f"must match peak_z {z.shape}")
    slopes = []
    for key in np.unique(g):
        sel = g == key
        ss = float(np.sum(s[sel] ** 2))
        if ss == 0.0:
            raise ArgumentError("presented_um", s[sel], f"group {key!r} needs a non-zero step height")
        slopes.append(float(np.sum(z[sel] * s[sel])) / ss)
    mean_slope = float(np.mean(slopes))
    if not mean_slope > 0:
        raise ArgumentError("peak_z", mean_slope, "mean regression slope must be > 0 "
                            "(the model responds to none of the steps)")
    return 1.0 / mean_slope


def accepted_height(peak_z, kappa: float) -> np.ndarray:
    """Accepted step height ŝ = κ·peak z (µm), shape of ``peak_z``."""
    if not (np.isfinite(kappa) and kappa > 0):
        raise ArgumentError("kappa", kappa, "conversion factor must be finite and > 0")
    return kappa * np.asarray(peak_z, dtype=float)


def log_choice_prob(s1_um, s2_um, sigma_d_um, lapse=0.0) -> tuple[np.ndarray, np.ndarray]:
    """log P(second judged higher) and log P(first judged higher) for accepted heights.

    Args:
        s1_um, s2_um (array_like[...]): accepted heights of the two stimuli (µm).
        sigma_d_um (array_like[...]): decision noise σ_d (µm), > 0.
        lapse (array_like[...]): lapse rate λ in [0, 1).
    Returns:
        (log_p, log_q) (ndarray[...]): broadcast shapes; exp(log_p) + exp(log_q) = 1.
    """
    sd = np.asarray(sigma_d_um, dtype=float)
    lam = np.asarray(lapse, dtype=float)
    if not np.all(np.isfinite(sd)) or np.any(sd <= 0):
        raise ArgumentError("sigma_d_um", sd, "decision noise (µm) must be finite and > 0")
    if not np.all(np.isfinite(lam)) or np.any(lam < 0) or np.any(lam >= 1):
        raise ArgumentError("lapse", lam, "lapse rate must be in [0, 1)")
    d = (np.asarray(s2_um, dtype=float) - np.asarray(s1_um, dtype=float)) / sd
    return log_lapse_ndtr(d, lam)


def choice_prob(s1_um, s2_um, sigma_d_um, lapse=0.0) -> np.ndarray:
    """P(second judged higher) = λ/2 + (1 − λ)·Φ((ŝ₂ − ŝ₁)/σ_d)."""
    return np.exp(log_choice_prob(s1_um, s2_um, sigma_d_um, lapse)[0])
