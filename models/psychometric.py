"""Psychometric function of a 2AFC "which step is higher" experiment.

A trial presents a standard (height s₀ at speed v_s) and a comparison (height x at
speed v_c) and asks which is higher. With a lapse rate λ the observer guesses on a
fraction λ of the trials, and a guess picks either stimulus with probability 1/2, so

    P(comparison judged higher | x) = λ/2 + (1 − λ)·Φ((x − PSE)/σ),

with Φ the standard normal CDF. The point of subjective equality (PSE) is where P = ½
(the symmetric guess rate keeps it at the centre of Φ for every λ).

**Difference threshold convention.** The difference threshold DT is the distance from
the PSE to the 75 % point of P itself (lapses included), i.e. P(PSE + DT) = 0.75:

    DT = σ · Φ⁻¹((0.75 − λ/2) / (1 − λ)),

which is σ·Φ⁻¹(0.75) ≈ 0.6745·σ without lapses and grows with λ; it exists only for
λ < ½ (at λ = ½ the function never reaches 75 %).

All probabilities are also available in log space (``scipy.special.log_ndtr``), exact
far into the tails where P itself rounds to 0 or 1.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import log_ndtr, ndtri

from feeler.errors import ArgumentError

__all__ = ["Psychometric", "p_higher", "log_p_higher", "dt_from_sigma", "sigma_from_dt",
           "log_lapse_ndtr", "LAPSE_MAX"]

LAPSE_MAX = 0.5  # a lapse rate at or above this leaves no 75 % point


def _check_sigma_lapse(sigma, lapse) -> tuple[np.ndarray, np.ndarray]:
    sigma = np.asarray(sigma, dtype=float)
    lapse = np.asarray(lapse, dtype=float)
    if not np.all(np.isfinite(sigma)) or np.any(sigma <= 0):
        raise ArgumentError("sigma", sigma, "spread sigma (µm) must be finite and > 0")
    if not np.all(np.isfinite(lapse)) or np.any(lapse < 0) or np.any(lapse >= LAPSE_MAX):
        raise ArgumentError("lapse", lapse, f"lapse rate must be in [0, {LAPSE_MAX})")
    return sigma, lapse


def log_p_higher(x, pse, sigma, lapse=0.0) -> tuple[np.ndarray, np.ndarray]:
    """log P(comparison judged higher) and log P(standard judged higher), both exact.

    Args:
        x (array_like[...]): comparison height (µm).
        pse (array_like[...]): point of subjective equality (µm).
        sigma (array_like[...]): spread of the cumulative normal (µm), > 0.
        lapse (array_like[...]): lapse rate λ in [0, 0.5).
    Returns:
        (log_p, log_q) (ndarray[...] each): log P and log(1 − P), broadcast shapes.
    """
    sigma, lapse = _check_sigma_lapse(sigma, lapse)
    z = (np.asarray(x, dtype=float) - np.asarray(pse, dtype=float)) / sigma
    return log_lapse_ndtr(z, lapse)


def log_lapse_ndtr(z, lapse) -> tuple[np.ndarray, np.ndarray]:
    """log(λ/2 + (1 − λ)Φ(z)) and log(λ/2 + (1 − λ)Φ(−z)) without under- or overflow.

    ``z (...)`` standardised difference, ``lapse (...)`` in [0, 1) (not checked here).
    """
    lapse = np.asarray(lapse, dtype=float)
    with np.errstate(divide="ignore"):           # log(0) = -inf for lapse 0 is intended
        log_guess = np.log(lapse / 2.0)
        log_keep = np.log1p(-lapse)
    return (np.logaddexp(log_guess, log_keep + log_ndtr(z)),
            np.logaddexp(log_guess, log_keep + log_ndtr(-z)))


def p_higher(x, pse, sigma, lapse=0.0) -> np.ndarray:
    """P(comparison judged higher) = λ/2 + (1 − λ)·Φ((x − PSE)/σ); shapes broadcast."""
    return np.exp(log_p_higher(x, pse, sigma, lapse)[0])


def dt_from_sigma(sigma, lapse=0.0) -> np.ndarray:
    """Difference threshold DT = σ·Φ⁻¹((0.75 − λ/2)/(1 − λ)) in the unit of σ."""
    sigma, lapse = _check_sigma_lapse(sigma, lapse)
    return sigma * ndtri((0.75 - lapse / 2.0) / (1.0 - lapse))


def sigma_from_dt(dt, lapse=0.0) -> np.ndarray:
    """The spread σ whose difference threshold at lapse λ is ``dt`` (inverse of
    :func:`dt_from_sigma`)."""
    dt = np.asarray(dt, dtype=float)
    if not np.all(np.isfinite(dt)) or np.any(dt <= 0):
        raise ArgumentError("dt", dt, "difference threshold (µm) must be finite and > 0")
    _check_sigma_lapse(1.0, lapse)
    lapse = np.asarray(lapse, dtype=float)
    return dt / ndtri((0.75 - lapse / 2.0) / (1.0 - lapse))


@dataclass(frozen=True)
class Psychometric:
    """One psychometric function.

    Attributes:
        pse_um (float): point of subjective equality (µm).
        sigma_um (float): spread of the cumulative normal (µm), > 0.
        lapse (float): lapse rate λ in [0, 0.5).
    """
    pse_um: float
    sigma_um: float
    lapse: float = 0.0

    def __post_init__(self):
        _check_sigma_lapse(self.sigma_um, self.lapse)
        if not np.isfinite(self.pse_um):
            raise ArgumentError("pse_um", self.pse_um, "must be finite")

    @property
    def dt_um(self) -> float:
        """Difference threshold (µm): distance from the PSE to the 75 % point."""
        return float(dt_from_sigma(self.sigma_um, self.lapse))

    def p_higher(self, x_um) -> np.ndarray:
        """P(comparison judged higher) at comparison heights ``x_um (...)``."""
        return p_higher(x_um, self.pse_um, self.sigma_um, self.lapse)

    def log_p_higher(self, x_um) -> tuple[np.ndarray, np.ndarray]:
        """(log P, log(1 − P)) at comparison heights ``x_um (...)``."""
        return log_p_higher(x_um, self.pse_um, self.sigma_um, self.lapse)
