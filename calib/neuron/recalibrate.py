"""Sharpening of the pooled plate probabilities, fitted by leave-one-out on the training scans.

The decoder averages each posterior draw's plate probabilities over its windows τ (a
linear pool, :mod:`.decoder`). A linear pool of calibrated forecasts is under-confident
(Ranjan & Gneiting 2010, "Combining probability forecasts"): averaging windows that the
scans cannot tell apart pulls every probability towards the middle. Measured on the hard
scenes (``benchmarks/test_bench_confidence.py``) the pooled probabilities were 3–5 points
below the observed accuracy in every confidence bin (ECE 0.025–0.036).

The correction is the beta-transformed family's one-parameter member, a power γ:

    p̃(c | scan) = (1 − ε)·p(c)^γ / Σ_c' p(c')^γ + ε/C,

with γ the maximum a posteriori value of the leave-one-out log score of the training
labels (:func:`~feeler.calib.neuron.window.loo_class_log_prob`: each scan classified by
the plates fitted without it, pooled over τ with the fit's weights) under a prior on ln γ
that is tighter above 0 than below: ln γ ~ Normal(0, 0.35²) for γ > 1 (sharpening) and
Normal(0, 1²) for γ < 1 (flattening towards even odds) — γ = 1 unless the labels say
otherwise. The sharpening side's sd was chosen among 0.25, 0.35 and 0.5 by the log-loss
of fresh touches (the confidence benchmark's eleven hard scenes and its control, and
seven altered scenes never shipped; 10 training sets each): against 0.5, 0.35 lowered it
on 14 of the 19 scenes (by up to 0.0067 nats a touch; the five others rose by at most
0.0026) and the control's ECE fell 0.031 → 0.025. Fitted from a few dozen training
scans, a loose γ follows their chance: on one altered scene three of ten fits, with γ of
1.25–1.34, were over-confident (confidence 0.79–0.84 against accuracy 0.66–0.76).

The flattening side is looser because the two errors are not alike. A mode whose touches
read at chance (rides at a window too short for their rise: accuracy 0.29–0.43 on three
plates) needs γ well below 1, and at sd 0.35 twenty such scans could not pull γ below
0.8: those rides were read at confidence 0.36–0.47, and the scene was over-confident
overall. With sd 1 below (session 47; the open-world benchmark's generator): on family
20261129, which no change was tuned on (16 training sets a scene), mean ECE over its 10
scenes of accuracy 0.6–0.95 fell 0.0284 → 0.0271 (ECE ≤ 0.03 in 5 of them, was 4;
random-13 0.048 → 0.043, random-17 0.045 → 0.038) and log-loss fell by 0.0013 nats a
touch (se 0.0006) over its 20 scenes; on family 20261128 (32 sets) mean ECE went
0.0184 → 0.0177 (14 of 16, as before) and log-loss rose by 0.0002 (se 0.0002); on the
confidence benchmark's eleven hard scenes and its control (10 sets) log-loss rose by
0.0008 (se 0.0004; 10 of 12 rose, by at most 0.004), ECE moved by at most 0.007
(exponential-fast-frames 0.024 → 0.017, three-exponential 0.012 → 0.015) and no plate's
coverage moved; on a third family, 20261130 (8 sets a scene), also untuned, ECE ≤ 0.03
in 7 of 10 either way, mean 0.0246 → 0.0241, the largest 0.0625 → 0.0563, and log-loss
rose by 0.0005 (se 0.0003). A small gain in calibration where the decoder was furthest
off, then, for a small cost in log-loss elsewhere.
ε = :data:`FLOOR` is a
fixed floor: a touch unlike every training touch of its plate (a tilted face, a snag)
must not cost more than ln(C/ε) nats, whatever the Gaussian tails say; 10⁻³ moves no
probability by more than 0.001.
"""
from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar
from feeler.errors import ArgumentError

__all__ = ["FLOOR", "LOG_GAMMA_SD", "LOG_GAMMA_SD_FLAT", "fit_sharpness", "recalibrated", "log_sum_exp"]

FLOOR = 1e-3            # ε, the probability spread evenly over the plates
LOG_GAMMA_SD = 0.35     # prior sd of ln γ above 0 (sharpening)
LOG_GAMMA_SD_FLAT = 1.0  # prior sd of ln γ below 0 (flattening towards even odds)
_LOG_GAMMA_BOUNDS = (-4.0, 2.0)     # search bounds of ln γ: γ in [0.018, 7.4]


def log_sum_exp(x: np.ndarray, axis: int, *, keepdims: bool = False) -> np.ndarray:
    """log Σ exp(x) along ``axis``, shifted by the maximum (−inf where every term is −inf).

    scipy's ``logsumexp`` does the same with array-API checks that cost ~0.1 ms a call,
    which the live decoder makes several times per sample."""
    m = np.max(x, axis=axis, keepdims=True)
    m = np.where(np.isfinite(m), m, 0.0)
    with np.errstate(divide="ignore"):
        out = np.log(np.sum(np.exp(x - m), axis=axis, keepdims=True)) + m
    return out if keepdims else np.squeeze(out, axis=axis)


def recalibrated(log_prob: np.ndarray, sharpness: float = 1.0, floor: float = 0.0) -> np.ndarray:
    """log p̃ of ``log_prob (ndarray[..., C])`` (normalised over the last axis) for power
    ``sharpness`` γ > 0 and ``floor`` ε in [0, 1)."""
    if not (np.isfinite(sharpness) and sharpness > 0):
        raise ArgumentError("sharpness", sharpness, "a finite number > 0")
    if not (0.0 <= floor < 1.0):
        raise ArgumentError("floor", floor, "a number in [0, 1)")
    lp = np.asarray(log_prob, float)
    if sharpness == 1.0 and floor == 0.0:
        return lp
    q = sharpness * lp
    q = q - log_sum_exp(q, axis=-1, keepdims=True)
    if floor == 0.0:
        return q
    with np.errstate(divide="ignore"):          # a subnormal floor / C rounds to 0: log 0 = −inf, no floor
        return np.logaddexp(np.log1p(-floor) + q, np.log(floor / lp.shape[-1]))


def fit_sharpness(loo_log_prob: np.ndarray, group: np.ndarray, *, floor: float = FLOOR) -> float:
    """γ maximising Σ_k log p̃(c_k | scan k) + log prior, from the leave-one-out plate
    probabilities ``loo_log_prob (ndarray[n_scans, C])`` and labels ``group (ndarray[n_scans]
    int)``. Returns 1.0 when the probabilities carry no information (all equal, or not finite)."""
    lp = np.asarray(loo_log_prob, float)
    g = np.asarray(group, int)
    if lp.ndim != 2 or g.shape != (lp.shape[0],):
        raise ArgumentError("loo_log_prob", lp.shape, "ndarray[n_scans, C] with one label per scan")
    if not np.all(np.isfinite(lp)) or np.ptp(lp) < 1e-12:
        return 1.0
    rows = np.arange(g.size)

    def neg_log_post(log_gamma):
        score = recalibrated(lp, float(np.exp(log_gamma)), floor)[rows, g].sum()
        sd = LOG_GAMMA_SD if log_gamma > 0 else LOG_GAMMA_SD_FLAT
        return -(score - 0.5 * (log_gamma / sd) ** 2)

    best = minimize_scalar(neg_log_post, bounds=_LOG_GAMMA_BOUNDS, method="bounded",
                           options={"xatol": 1e-4})
    return float(np.exp(best.x))
