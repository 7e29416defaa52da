"""Cell means pooled along the calibration line: a two-mode model's reference prior.

Under the reference prior (κ₀ = 0, :mod:`.conjugate`) every (plate, mode) cell has a mean
of its own, flat and independent of the others. A cell holds 1-6 touches on the hard
scenes, so the means of cells that truly sit together scatter by σ/√n and the plates read
apart: on random untuned scenes whose rides barely tell their plates apart
(``benchmarks/test_bench_open_world.py``'s generator, three plates 9-28 um apart, 8-14
rides a training set) rides decoded at accuracy 0.37-0.42 with confidence 0.46-0.50.
The peak P of one mode rises with the step along a line, so the means of one mode's
cells are given a prior that knows it:

    μ_c = α + β x_c + δ_c,   δ_c ~ Normal(0, ω²),   (α, β) flat,

with x_c the cell's step. ω is drawn on :data:`NODES` log-spaced nodes from
:data:`RANGE` times the cells' mean standard error s̄ = √(mean_c σ_c²/n_c), equal prior
mass on each: below 0.05 s̄ the means lie on the line, above 100 s̄ they are the flat
model's, and the prior splits its mass between the two ends and the range where the data
decide. Given σ (drawn from the cells' within-cell scatter, :func:`.conjugate.draw_plate_parameters`)
everything is Gaussian (a linear mixed model; REML for ω): with V_c = σ_c²/n_c + ω²,
W = V⁻¹ and r = x̄ − X b̂ (b̂ the weighted least-squares line),

    p(ω | x̄, σ) ∝ |V|^(−1/2) |XᵀWX|^(−1/2) exp(−rᵀWr / 2),
    b | ω ~ Normal(b̂, (XᵀWX)⁻¹),
    μ_c | b, ω ~ Normal((x̄_c n_c/σ_c² + (Xb)_c/ω²) / (n_c/σ_c² + 1/ω²), 1 / (n_c/σ_c² + 1/ω²)).

A plate of step 0 has no riser to ride over or snap onto: its touches read the baseline,
not a point of the rides' line, and its mean stays the flat model's (pooled with the
risers, the floor's coverage fell on seven random scenes by 0.01-0.03, to 0.81-0.89;
kept apart, 0.84-0.90 as with flat means, at the same log-loss). Fewer than three risers
leave no scatter about a line to learn ω from; their means stay the flat model's too. The
leave-one-out scores that choose the noise model and fit the sharpness γ
(:mod:`.window`) keep the flat means.

Measured against the flat means, by the log-loss of fresh touches (a proper score):
on the confidence benchmark's eleven hard scenes and its control (10 training sets each)
it fell on 11 of the 12, by 0.0052 a touch on average (se 0.0019; six-plates-few 0.475 →
0.452, its accuracy 0.832 → 0.850); ECE 0.008-0.028 on the eleven (0.008-0.025 before),
0.030 on the control (0.024); the same three of the 46 plates outside 0.85-0.95
(close-steps' lowest 0.953, five-plates-long-window's floor 0.836, uneven-steps' 0.012 mm
plate 0.961, was 0.970). On the open-world benchmark's 16 random scenes with accuracy
0.6-0.95 (8 sets each) it fell on 14, by 0.0066 on average (se 0.0018); ECE ≤ 0.03 on 12
of them as before (mean 0.0240 → 0.0232). At full size (``FEELER_FULL=1``: 40 scenes, 10
sets, 200 fresh touches a plate; 30 in the range) it fell on 23 of 30 (mean −0.0056, se
0.0015), ECE ≤ 0.03 on 24 against 23; the lowest plate, when it has a riser, lost 0.007 of
coverage on average (at most 0.03: 0.81 → 0.78 on one scene), the others none. The rides of
three evenly spaced plates gain nothing: the line's slope, which carries their whole
difference, is as uncertain as the end cells' means.
"""
from __future__ import annotations

import numpy as np

__all__ = ["pooled_means", "omega_log_posterior", "NODES", "RANGE", "BLOCK"]

NODES = 40                  # nodes of ω
RANGE = (0.05, 100.0)       # ω / s̄ at the first and the last node
BLOCK = 512                 # draws a block (omega_log_posterior of 4000 draws: 30 ms at once, 11 ms in blocks)


def _line_design(steps: np.ndarray) -> np.ndarray:
    """[1, x_c] with x scaled to a span of 1 (for a well-conditioned XᵀWX)."""
    x = np.asarray(steps, float)
    span = float(np.ptp(x))
    return np.column_stack([np.ones(x.size), (x - x.min()) / (span if span > 0 else 1.0)])


def omega_log_posterior(mean: np.ndarray, se_sq: np.ndarray, steps: np.ndarray, omega_sq: np.ndarray):
    """log p(ω | x̄, σ) + const at ``omega_sq (ndarray[S, G])`` for cell means ``mean`` and
    their squared standard errors σ_c²/n_c ``se_sq`` (ndarray[S, K]) → (log p ndarray[S, G],
    b̂ ndarray[S, G, 2], the entries (A₀₀, A₀₁, A₁₁) of XᵀWX, each ndarray[S, G]).

    Written for speed (a fit makes six calls on 4000 draws × 40 nodes; :func:`pooled_means`
    passes them in blocks of :data:`BLOCK`): the 2 × 2 algebra by hand and every sum over
    the cells as a matrix product (numpy's batched solve and slogdet, and sums over a short
    last axis, took the default fit from 0.34 s to 0.82 s); the
    residual sum of squares as x̄ᵀWx̄ − b̂ᵀXᵀWx̄ on means centred per draw (the line's
    intercept takes the centre back)."""
    x = _line_design(steps)[:, 1]
    centre = mean.mean(axis=1, keepdims=True)
    m = mean - centre
    V = se_sq[:, None, :] + omega_sq[:, :, None]                               # (S, G, K)
    W = 1.0 / V
    K = x.size
    a00, a01, a11 = W @ np.ones(K), W @ x, W @ (x * x)
    Wm = W * m[:, None, :]
    r0, r1, mwm = Wm @ np.ones(K), Wm @ x, np.matmul(Wm, m[:, :, None])[..., 0]
    det = a00 * a11 - a01 ** 2
    b0, b1 = (a11 * r0 - a01 * r1) / det, (a00 * r1 - a01 * r0) / det
    quad = np.maximum(mwm - b0 * r0 - b1 * r1, 0.0)
    logp = -0.5 * (np.log(V) @ np.ones(K) + np.log(det) + quad)
    return logp, np.stack([b0 + centre, b1], axis=-1), (a00, a01, a11)


def pooled_means(rng: np.random.Generator, mean: np.ndarray, sigma: np.ndarray, counts: np.ndarray,
                 steps: np.ndarray) -> np.ndarray:
    """Draws of the cell means μ (ndarray[S, K]) given each draw's cell means of P ``mean``
    and σ ``sigma`` (ndarray[S, K]), the cells' scan counts and steps (ndarray[K]); see
    the module docstring. Cells of step ≤ 0, and all of them when fewer than three cells
    have a riser: the flat model's draws."""
    mean, sigma = np.asarray(mean, float), np.asarray(sigma, float)
    steps = np.asarray(steps, float)
    se_sq = sigma ** 2 / np.asarray(counts, float)
    riser = steps > 0
    if riser.all() and riser.size >= 3:
        return _pooled(rng, mean, se_sq, steps)
    out = mean + np.sqrt(se_sq) * rng.standard_normal(mean.shape)          # the flat model's draws
    if riser.sum() >= 3:                    # a plate without a riser keeps its own mean
        out[:, riser] = _pooled(rng, mean[:, riser], se_sq[:, riser], steps[riser])
    return out


def _pooled(rng: np.random.Generator, mean: np.ndarray, se_sq: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """:func:`_pooled_block` a block of :data:`BLOCK` draws at a time: its temporaries stay in cache."""
    return np.concatenate([_pooled_block(rng, mean[a:a + BLOCK], se_sq[a:a + BLOCK], steps)
                           for a in range(0, mean.shape[0], BLOCK)])


def _pooled_block(rng: np.random.Generator, mean: np.ndarray, se_sq: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """:func:`pooled_means` of cells that all have a riser, from their squared standard errors."""
    S = mean.shape[0]
    scale_sq = np.mean(se_sq, axis=1)                                         # s̄²
    ratio = np.geomspace(*RANGE, NODES)
    omega_sq = scale_sq[:, None] * ratio[None, :] ** 2                       # (S, G)
    logp, b, (a00, a01, a11) = omega_log_posterior(mean, se_sq, steps, omega_sq)
    p = np.exp(logp - logp.max(axis=1, keepdims=True))
    cdf = np.cumsum(p, axis=1)
    j = np.minimum((cdf < rng.uniform(size=S)[:, None] * cdf[:, -1:]).sum(axis=1), NODES - 1)
    rows = np.arange(S)
    o2, a00, a01, a11 = omega_sq[rows, j], a00[rows, j], a01[rows, j], a11[rows, j]
    det = a00 * a11 - a01 ** 2
    c00, c01, c11 = a11 / det, -a01 / det, a00 / det                       # (XᵀWX)⁻¹
    l00 = np.sqrt(c00)
    l10 = c01 / l00
    l11 = np.sqrt(np.maximum(c11 - l10 ** 2, 0.0))
    z = rng.standard_normal((S, 2))
    line = b[rows, j] + np.column_stack([l00 * z[:, 0], l10 * z[:, 0] + l11 * z[:, 1]])
    prior_mean = line @ _line_design(steps).T                                 # (S, K)
    precision = 1.0 / se_sq + 1.0 / o2[:, None]
    centre = (mean / se_sq + prior_mean / o2[:, None]) / precision
    return centre + rng.standard_normal(mean.shape) / np.sqrt(precision)
