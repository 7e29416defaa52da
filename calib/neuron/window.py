"""Weights of the window τ and the choice of the noise model, by leave-one-out prediction.

For each τ of the peak table and each noise model, every training scan k is decoded by
the plates fitted without it: the continuous decoder's density of its label,

    p(δ_k | P_k) = N(P_k; μ_c, s_c) / ∫ N(P_k; μ(δ), s(δ)) dδ,   c = δ_k,

with μ(δ), s(δ) the calibration curve (piecewise linear through the plates, extended
linearly past the end plates with constant spread; :mod:`.decoder`) and s_c the
predictive spread s·√(1 + 1/n_c) of the plate's plug-in fit (the integral per segment by
Gauss–Legendre, see :func:`continuous_log_density`). The sum over scans is the
expected log predictive density (elpd) of the labels; it compares windows on the same
data (the labels), unlike the density of P(τ), which differs with τ. Weights
∝ prior × exp(elpd), averaged over Bayesian-bootstrap resamples of the scans, are
pseudo-BMA+ (Yao et al. 2018; :func:`tau_log_weights`). A decoder whose curve is flat
or turns down somewhere cannot be inverted and gets elpd = −∞ there. The noise model is
chosen by the total (log Σ_τ prior·exp(elpd)); per-plate spreads must earn their extra
parameters by two standard errors (:func:`choose_noise`). The two-mode models are
compared as they are used: with a spread per mode when the modes have the scans for it
(:func:`loo_two_mode`). (They used to be compared with one spread for both and then
rescored with their own; the choice between one-mode and two-mode came out the same in
all 120 training sets of the eleven hard scenes and the control, and the confidence
benchmark's rows moved by at most 0.006 in accuracy, 0.0022 in ECE and 0.027 in a
plate's coverage.) Under a two-mode
model (:mod:`.modes`) a scan is decoded by the curve of its own mode (snap or ride, read from
the scan as :func:`~feeler.calib.neuron.classify.classify` reads a new one), made
monotone as the decoder makes it (:func:`.decoder.monotone_curve`: isotonic, and past
its ends at least a tenth of the plates' mean slope). A mode's curve, from 1–6 touches a
plate, turns down by chance: read as it came, 15–93 % of the windows scored −∞ on the
nine hard scenes, an untuned control and five altered scenes (ten training sets each),
and in up to 5 of 10 sets every window did, which ruled the two-mode models out.
"""
from __future__ import annotations

import numpy as np
from scipy.special import logsumexp, ndtr

from feeler.calib.neuron.conjugate import G_NODES, growth_log_density
from feeler.calib.neuron.decoder import monotone_curve
from feeler.calib.neuron.model import NOISE_MODELS, PeakTable, PlatePrior, Plates, plate_stats
from feeler.calib.neuron.modes import Cells, within_noise

__all__ = ["alone", "loo_plates", "loo_class_log_prob", "loo_class_cond", "pooled_class_log_prob", "loo_elpd", "choose_noise", "tau_log_weights", "continuous_log_density",
           "loo_two_mode", "usable_noise_models"]


def usable_noise_models(plates: Plates) -> tuple[str, ...]:
    """Noise models the counts allow: per-plate needs ≥ 3 scans on every plate (a
    leave-one-out spread needs 2); the pooled ones ≥ 2 degrees of freedom overall."""
    out = []
    if plates.steps_mm.size >= 2 and plates.counts.sum() - plates.steps_mm.size >= 3:
        out += ["constant", "growing"]
    if plates.steps_mm.size >= 2 and plates.counts.min() >= 3:
        out.append("per-plate")
    if plates.steps_mm.size >= 2 and plates.snap is not None:
        cells = Cells(plates, plates.snap)
        if cells.snaps and cells.rides and plates.counts.sum() - cells.size >= 3:
            out += ["two-mode", "two-mode-growing"]
    return tuple(m for m in NOISE_MODELS if m in out)


_GL_T, _GL_W = np.polynomial.legendre.leggauss(24)
_QUADRATURE_BLOCK = 4e6         # quadrature nodes held at once by loo_elpd (32 MB per temporary)


def _segment_integral(lo, hi, kappa):
    """∫_lo^hi φ(t)/(1 − κt) dt (Gauss–Legendre on the part within ±10), elementwise."""
    a, b = np.clip(lo, -10.0, 10.0), np.clip(hi, -10.0, 10.0)
    half, mid = 0.5 * (b - a), 0.5 * (b + a)
    t = mid[..., None] + half[..., None] * _GL_T
    f = np.exp(-0.5 * t * t) / np.sqrt(2 * np.pi) / (1.0 - kappa[..., None] * t)
    return half * np.sum(_GL_W * f, axis=-1)


def continuous_log_density(p, c_index, mu, s, steps, end_slopes=None) -> np.ndarray:
    """log p(δ = steps[c_index] | P = p) under the calibration curve through (steps, mu)
    with spreads s; broadcast over leading axes. ``mu, s`` ndarray[..., C]; ``p``,
    ``c_index`` ndarray[...]. −inf where the curve turns down. ``end_slopes
    (ndarray[..., 2])``: the curve's slopes past its ends (:func:`.decoder.monotone_curve`;
    by default the end segments').

    Per segment the curve u = μ(δ) and its spread are linear, so with t = (u − p)/s(u)
    the integral ∫ N(p; u, s(u)) du equals ∫ φ(t)/(1 − κt) dt, κ = ds/du: a smooth
    integrand, done by Gauss–Legendre; on a flat segment (a monotone curve's pooled
    plates) the integral over δ directly, whose integrand is smooth there too; past the end
    plates the spread is constant and the integral is a difference of Φ."""
    steps = np.asarray(steps, float)
    dc = np.diff(steps)
    dm = np.diff(mu, axis=-1)
    beta = dm / dc                                                              # P per mm, (..., C-1)
    # a spread near 0 (a degenerate set's plate) overflows the ratios to ±inf: handled below
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        kappa = np.where(dm > 0, np.diff(s, axis=-1) / dm, 0.0)
        lo = (mu[..., :-1] - p[..., None]) / s[..., :-1]
        hi = (mu[..., 1:] - p[..., None]) / s[..., 1:]
        seg = np.where(beta > 0, _segment_integral(lo, hi, kappa) / beta, np.inf)
        if np.any(beta == 0):
            seg = np.where(beta == 0, dc * _flat_segment_mean(p, mu[..., :-1], s[..., :-1], s[..., 1:]), seg)
        ends = np.stack([beta[..., 0], beta[..., -1]], axis=-1) if end_slopes is None else end_slopes
        tail_lo = np.where(ends[..., 0] > 0, ndtr((mu[..., 0] - p) / s[..., 0]) / ends[..., 0], np.inf)
        tail_hi = np.where(ends[..., 1] > 0, ndtr((p - mu[..., -1]) / s[..., -1]) / ends[..., 1], np.inf)
        z = np.sum(seg, axis=-1) + tail_lo + tail_hi
        m_c = np.take_along_axis(mu, c_index[..., None], axis=-1)[..., 0]
        s_c = np.take_along_axis(s, c_index[..., None], axis=-1)[..., 0]
        num = -0.5 * ((p - m_c) / s_c) ** 2 - np.log(s_c) - 0.5 * np.log(2 * np.pi)
        out = num - np.log(z)
    return np.where(np.isfinite(out), out, -np.inf)


def _flat_segment_mean(p, m, s0, s1):
    """The mean of N(p; m, s(δ)) over a segment where the curve is flat at ``m`` and its
    spread runs linearly from ``s0`` to ``s1`` (Gauss–Legendre), elementwise (..., C−1)."""
    frac = 0.5 * (_GL_T + 1.0)
    sd = s0[..., None] + frac * (s1 - s0)[..., None]
    dens = np.exp(-0.5 * ((p[..., None, None] - m[..., None]) / sd) ** 2) / (sd * np.sqrt(2 * np.pi))
    return 0.5 * np.sum(_GL_W * dens, axis=-1)


def _growth_hat(q, r, x, prior: PlatePrior, growth_max: float) -> np.ndarray:
    nodes = np.linspace(-growth_max, growth_max, G_NODES)
    lp = growth_log_density(nodes, q, r, x, prior)
    return nodes[np.argmax(lp, axis=1)]


def loo_plates(table: PeakTable, plates: Plates, noise: str, *, growth_max: float = 3.0, shared_spread: bool = False):
    """Every scan's view of the plates fitted without it, per τ node: the plate means and
    predictive spreads s·√(1 + 1/n_c) of the plug-in fit of one noise model, two
    ndarray[n_grid, n_scans, C] (units of P). Under a two-mode model, the plates of the
    scan's own mode (:func:`loo_two_mode`, ``shared_spread`` passed on)."""
    if within_noise(noise):
        return loo_two_mode(table, plates, within_noise(noise), growth_max=growth_max, shared_spread=shared_spread)
    p = table.peak.T                                                        # (G, n)
    mean, ss = plate_stats(p, plates)                                       # (G, C)
    n_c = plates.counts.astype(float)
    C, G, n = n_c.size, p.shape[0], p.shape[1]
    g_idx = plates.group
    # remove scan k from its plate (Welford): (G, n) for the scan's own plate; a scan alone
    # on its plate leaves none (NaN: see :func:`alone`)
    own_mean, own_n = mean[:, g_idx], n_c[g_idx]
    with np.errstate(divide="ignore", invalid="ignore"):
        loo_mean_own = (own_n * own_mean - p) / (own_n - 1)
        loo_ss_own = np.where(own_n > 1, np.maximum(ss[:, g_idx] - (p - own_mean) ** 2 * own_n / (own_n - 1), 0.0),
                              0.0)                                          # alone: adds no spread
    mu = np.repeat(mean[:, None, :], n, axis=1)                             # (G, n, C)
    ssk = np.repeat(ss[:, None, :], n, axis=1)
    nk = np.repeat(n_c[None, :], n, axis=0)                                 # (n, C)
    rows = np.arange(n)
    mu[:, rows, g_idx] = loo_mean_own
    ssk[:, rows, g_idx] = loo_ss_own
    nk[rows, g_idx] -= 1
    floor = (1e-12 * np.max(np.abs(mean), axis=1))[:, None, None] ** 2
    if noise == "per-plate":
        var = np.maximum(ssk / (nk - 1), floor)
    else:
        var = _pooled_var(ssk, _spread_shape(ss, plates, noise, growth_max)[:, None, :], n - 1 - C, floor)
    with np.errstate(divide="ignore", invalid="ignore"):           # a lone scan's own plate: nk = 0
        return mu, np.sqrt(var * (1 + 1 / nk))


def _fitted_spreads(p: np.ndarray, plates: Plates, noise: str, growth_max: float) -> np.ndarray:
    """The predictive spreads s·√(1 + 1/n_c) of the pooled (``constant`` or ``growing``)
    plug-in fit of all the scans ``p (ndarray[n_grid, n_scans])``, ndarray[n_grid, C]:
    :func:`loo_plates` with no scan left out."""
    mean, ss = plate_stats(p, plates)
    n_c = plates.counts.astype(float)
    floor = (1e-12 * np.max(np.abs(mean), axis=-1, keepdims=True)) ** 2
    var = _pooled_var(ss, _spread_shape(ss, plates, noise, growth_max), p.shape[-1] - n_c.size, floor)
    return np.sqrt(var * (1 + 1 / n_c))


def _spread_shape(ss: np.ndarray, plates: Plates, noise: str, growth_max: float) -> np.ndarray:
    """σ_c/σ₀ of a pooled noise model fitted to the plates' sums of squares ``ss
    (ndarray[G, C])``: e^(ĝ x_c) (``growing``, ĝ the mode of g) ndarray[G, C], else ones
    ndarray[1, C]."""
    if noise != "growing":
        return np.ones((1, ss.shape[-1]))
    g = _growth_hat(ss, plates.counts - 1.0, plates.x, PlatePrior(), growth_max)       # (G,)
    return np.exp(g[:, None] * plates.x[None, :])


def _pooled_var(ss: np.ndarray, shape: np.ndarray, dof: float, floor) -> np.ndarray:
    """σ_c² of the pooled plug-in fit: σ₀² = Σ_c SS_c/shape_c² / dof, times shape_c², at
    least ``floor``; ``ss`` and ``shape`` broadcast with the plates last."""
    return np.maximum(np.sum(ss / shape ** 2, axis=-1, keepdims=True) / dof * shape ** 2, floor)


def loo_two_mode(table: PeakTable, plates: Plates, within: str = "constant", *, growth_max: float = 3.0,
                 mixture: bool = False, shared_spread: bool = False):
    """Every scan's view of the two-mode plates fitted without it, per τ node, in the
    scan's own mode (as classify reads a new scan): the plates' means and predictive
    spreads in that mode (each a (plate, mode) cell of the pooled ``within`` fit,
    :func:`loo_plates`; the ride and the snap cells pooled apart when both modes have
    the scans for a spread curve of their own, :attr:`.modes.Cells.own_spreads`, unless
    ``shared_spread``), two ndarray[n_grid, n_scans, C]. A mode left without scans takes
    the other mode's mean and spread. ``mixture``: a third, the plates' means over both
    modes (weights the shares of snaps and rides), whose slope bounds the mode's curve
    past its ends as in the decoder (:func:`.decoder.monotone_curve`)."""
    cells = Cells(plates, plates.snap)
    mu, s = loo_plates(table, cells.as_plates, within, growth_max=growth_max)  # (G, n, K)
    if cells.own_spreads and not shared_spread:       # every cell's spread from its own mode's pool
        for k in (0, 1):
            keep, scans, sub = cells.of_mode(k)
            m_k, s_k = loo_plates(PeakTable(log_tau=table.log_tau, peak=table.peak[scans]), sub, within,
                                  growth_max=growth_max)
            rows = np.flatnonzero(scans)[:, None]
            mu[:, rows, keep], s[:, rows, keep] = m_k, s_k
            # the other mode's scans see these cells whole (a cell they borrow where their own is empty)
            s[:, np.flatnonzero(~scans)[:, None], keep] = _fitted_spreads(table.peak[scans].T, sub, within,
                                                                          growth_max)[:, None, :]
    ride, snap = mu[..., cells.index[:, 0]], mu[..., cells.index[:, 1]]
    s_ride, s_snap = s[..., cells.index[:, 0]], s[..., cells.index[:, 1]]
    empty_r, empty_s = ~np.isfinite(ride), ~np.isfinite(snap)
    ride, s_ride = np.where(empty_r, snap, ride), np.where(empty_r, s_snap, s_ride)
    snap, s_snap = np.where(empty_s, ride, snap), np.where(empty_s, s_ride, s_snap)
    own = plates.read[None, :, None]
    views = np.where(own, snap, ride), np.where(own, s_snap, s_ride)
    if not mixture:
        return views
    share = cells.snaps / max(cells.snaps + cells.rides, 1)
    return (*views, (1.0 - share) * ride + share * snap)


def loo_elpd(table: PeakTable, plates: Plates, noise: str, *, growth_max: float = 3.0,
             pointwise: bool = False, shared_spread: bool = False) -> np.ndarray:
    """Leave-one-out elpd of the labels per τ node (ndarray[n_grid]) for one noise model
    (``pointwise``: per node and scan, ndarray[n_grid, n_scans]; ``shared_spread``:
    :func:`loo_two_mode`)."""
    if within_noise(noise):        # a scan read by its mode's curve, made monotone as the decoder makes it
        mu, s, plate_curve = loo_two_mode(table, plates, within_noise(noise), growth_max=growth_max, mixture=True,
                                          shared_spread=shared_spread)
    else:
        mu, s = loo_plates(table, plates, noise, growth_max=growth_max)
    G, n, C = mu.shape
    p = table.peak.T
    dens = np.empty((G, n))
    # scans a block at a time: the quadrature holds G × scans × (C − 1) × 24 nodes in several
    # temporaries (2000 scans at once peaked at 1.56 GB); per element the same numbers
    block = max(1, int(_QUADRATURE_BLOCK // (G * max(C - 1, 1) * _GL_T.size)))
    for a in range(0, n, block):
        sl = slice(a, min(a + block, n))
        curve, ends = mu[:, sl], None
        if within_noise(noise):
            curve, ends = monotone_curve(plates.steps_mm, curve, plate_curve[:, sl])
        dens[:, sl] = continuous_log_density(p[:, sl], np.broadcast_to(plates.group[sl], (G, sl.stop - a)),
                                             curve, s[:, sl], plates.steps_mm, ends)
    dens = np.where(alone(plates), 0.0, dens)
    return dens if pointwise else np.sum(dens, axis=1)


def alone(plates: Plates, noise: str | None = None) -> np.ndarray:
    """Scans alone on their plate, ndarray[n_scans] bool: without them their plate has no
    scan, so no left-out prediction of them exists; they add nothing to the leave-one-out
    scores (the verdict fails such data: :func:`.checks.data_problems`).

    With a two-mode ``noise`` (passed by :func:`loo_class_cond`, whose probabilities fit
    the sharpness γ), also scans alone in their (plate, mode) cell: left out, their cell
    is empty and they are read by the other mode's curve, which no new scan of their mode
    meets, and confidently misread they pulled γ down (30 random untuned scenes, drawn as
    ``benchmarks/test_bench_open_world.py`` draws them but from a four-plates with more
    drift (0.5 um/s) and a gain of 2, 8 training sets each: mean ECE
    0.033 → 0.031 over the 16 with accuracy 0.6-0.95, one scene 0.053 → 0.032; on the
    confidence benchmark ECE moved by at most 0.005 and log-loss by at most 0.007). The
    window and model scores (:func:`loo_elpd`) keep them: left out there as well, the
    log-loss of three hard scenes with 60-80 % snaps rose by up to 0.03, and one-mode
    and two-mode models would be scored on different scans."""
    lone = plates.counts[plates.group] < 2
    if noise is not None and within_noise(noise):
        cells = Cells(plates, plates.snap).as_plates
        lone = lone | (cells.counts[cells.group] < 2)
    return lone


def loo_class_log_prob(table: PeakTable, plates: Plates, noise: str, log_w: np.ndarray, *,
                       growth_max: float = 3.0) -> np.ndarray:
    """log P(plate | scan k) of every training scan under the plates fitted without it,
    pooled over the τ nodes with weights ``exp(log_w) (ndarray[n_grid])`` as the decoder
    pools its draws (equal plate priors): ndarray[n_scans, C]."""
    return pooled_class_log_prob(loo_class_cond(table, plates, noise, growth_max=growth_max), log_w)


def pooled_class_log_prob(cond: np.ndarray, log_w: np.ndarray) -> np.ndarray:
    """:func:`loo_class_log_prob` from its per-node plate probabilities ``cond``
    (:func:`loo_class_cond`), for one set of τ weights: the leave-one-out fits do not
    depend on the weights, so a fit with a decoder per mode computes them once."""
    keep = np.isfinite(log_w) & np.all(np.isfinite(cond), axis=(1, 2))
    if not keep.any():
        return np.full(cond.shape[1:], -np.log(cond.shape[2]))
    w = log_w[keep] - logsumexp(log_w[keep])
    return logsumexp(cond[keep] + w[:, None, None], axis=0)


def loo_class_cond(table: PeakTable, plates: Plates, noise: str, *, growth_max: float = 3.0) -> np.ndarray:
    """log P(plate | scan k) at each τ node under the plates fitted without scan k (equal
    plate priors; Student-t predictives), ndarray[n_grid, n_scans, C]; even odds for a
    scan alone on its plate or, two-mode, in its cell (:func:`alone`)."""
    from scipy.stats import t as student_t          # here: scipy.stats costs `classify` 0.4 s of imports

    mu, s = loo_plates(table, plates, noise, growth_max=growth_max)
    p = table.peak.T[..., None]                                             # (G, n, 1)
    nk = np.repeat(plates.counts[None, :].astype(float), p.shape[1], axis=0)
    nk[np.arange(p.shape[1]), plates.group] -= 1
    cells = Cells(plates, plates.snap) if within_noise(noise) else None
    pooled = cells.size if cells is not None else nk.shape[1]                      # means fitted
    dof = nk - 1 if noise == "per-plate" else np.full(nk.shape, p.shape[1] - 1.0 - pooled)
    if cells is not None and cells.own_spreads:          # a scan's mode pools its own cells
        per_mode = np.array([cells.as_plates.counts[cells.mode == k].sum() - np.sum(cells.mode == k)
                             for k in (0, 1)])
        read = plates.read.astype(int)          # the pool a scan is read by; less itself when it is in it
        dof = np.broadcast_to((per_mode[read] - (read == plates.snap))[:, None], nk.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        ll = student_t.logpdf(p, dof, loc=mu, scale=s)
    ll = np.where(np.isfinite(ll), ll, -np.inf)
    ll[:, alone(plates, noise), :] = 0.0                                   # no prediction: even odds
    return ll - logsumexp(ll, axis=2, keepdims=True)                         # per node


def tau_log_weights(pointwise: np.ndarray, rng: np.random.Generator, n_boot: int = 400) -> np.ndarray:
    """Normalised log weights of the τ nodes from the pointwise LOO densities
    ``pointwise (ndarray[n_grid, n_scans])``: pseudo-BMA+ (Yao et al. 2018), the mean of
    softmax(n·Σ_k α_k·log p_k(τ)) over Bayesian-bootstrap weights α ~ Dirichlet(1, …, 1)
    (uniform prior in ln τ). Plain exp(elpd) puts all weight on whichever window the
    training scans happen to favour by a few nats; the bootstrap spreads it over the
    windows that the scans cannot tell apart."""
    G, n = pointwise.shape
    if not np.any(np.isfinite(pointwise)):
        return np.full(G, -np.log(G))
    d = np.where(np.isfinite(pointwise), pointwise, -1e300)
    alpha = rng.dirichlet(np.ones(n), size=n_boot)                           # (B, n)
    elpd = n * alpha @ d.T                                                   # (B, G)
    w = np.exp(elpd - logsumexp(elpd, axis=1, keepdims=True)).mean(axis=0)
    with np.errstate(divide="ignore"):
        return np.log(w)


def choose_noise(table: PeakTable, plates: Plates, *, growth_max: float = 3.0,
                 candidates: tuple[str, ...] | None = None, explain: bool = False):
    """(chosen model, total log score per model, pointwise LOO densities of the chosen
    one, ndarray[n_grid, n_scans]); with ``explain``, a fourth item: why the model of the
    top score was not chosen (a dict: ``top``, ``chosen``, ``lead`` and ``two_se``, totals
    over the scans, and ``rule``: "per-plate" or "one-mode"), or None when the top score's
    model is the choice.

    The better of the two-mode models when the touches show both modes, unless the better
    of the one-mode pooled models (constant, growing) beats it by more than two standard
    errors: left out, a touch takes its (plate, mode) cell's mean with it, and cells hold
    1-6 touches on the hard scenes, so leave-one-out understates the two-mode models (on
    the eleven hard scenes, ten training sets each, choosing by the score alone picked a
    one-mode model in 0-7 of 10 sets and gave ECE 0.034 on short-window and on
    five-plates-long-window and accuracy 0.71 on three-exponential, against 0.027, 0.023
    and 0.76 with this rule). Else the better of the pooled
    one-mode models. ``per-plate`` only when it beats the choice by more than two standard
    errors: its extra spread parameters, fitted to ~10
    scans per plate, otherwise mostly fit chance — and the window is then weighted towards
    wherever a plate happens to look tight (cf. Vehtari, Gelman & Gabry 2017 on LOO
    differences within their noise). The standard error of the difference is that of the
    pointwise differences at each model's heaviest window, × √n."""
    models = candidates or usable_noise_models(plates)
    scores, curves, points = {}, {}, {}
    for m in models:
        dens = loo_elpd(table, plates, m, growth_max=growth_max, pointwise=True)
        e = np.sum(dens, axis=1)
        curves[m] = dens
        scores[m] = float(logsumexp(e) - np.log(e.size)) if np.any(np.isfinite(e)) else -np.inf
        points[m] = dens[int(np.argmax(e))]
    def beats(challenger, holder) -> bool:
        if challenger not in scores or not np.isfinite(scores[challenger]):
            return False
        diff = points[challenger] - points[holder]
        se = float(np.sqrt(diff.size) * np.std(diff)) if np.all(np.isfinite(diff)) else np.inf
        return scores[challenger] - scores[holder] > 2 * se

    two = [m for m in models if within_noise(m) and np.isfinite(scores[m])]
    one = [m for m in models if m in ("constant", "growing")]
    if two:
        best = max(two, key=scores.get)
        if one and beats(max(one, key=scores.get), best):
            best = max(one, key=scores.get)
    elif one:
        best = max(one, key=scores.get)
    else:
        return ("per-plate", scores, curves["per-plate"]) + ((None,) if explain else ())
    if beats("per-plate", best):
        best = "per-plate"
    if not explain:
        return best, scores, curves[best]
    return best, scores, curves[best], _passed_over(best, scores, points)


def _passed_over(best: str, scores: dict, points: dict) -> dict | None:
    """Why :func:`choose_noise` did not choose the model of the top score: it leads the
    choice by no more than two standard errors of the difference (the rule for per-plate,
    and for a one-mode model against a two-mode one)."""
    finite = {m: v for m, v in scores.items() if np.isfinite(v)}
    if not finite:
        return None
    top = max(finite, key=finite.get)
    if top == best or not finite[top] > scores[best]:
        return None
    diff = points[top] - points[best]
    se = float(np.sqrt(diff.size) * np.std(diff)) if np.all(np.isfinite(diff)) else float("inf")
    return {"top": top, "chosen": best, "lead": float(finite[top] - scores[best]), "two_se": 2 * se,
            "rule": "per-plate" if top == "per-plate" else "one-mode"}

