"""Cell means pooled along the calibration line (calib/neuron/pooling.py): the Gaussian
posterior given ω in closed form, ω's marginal against numerical integration over the
line, SBC of the whole layer, its limits, and its effect on a two-mode fit's cells."""
from __future__ import annotations

import numpy as np
import pytest

from feeler.calib.neuron import pooling
from feeler.calib.neuron.grid import two_mode_draws
from feeler.calib.neuron.model import PeakTable, Plates, make_priors
from feeler.calib.sbc import run_sbc

STEPS = np.array([0.01, 0.02, 0.03, 0.06])
COUNTS = np.array([5.0, 3.0, 4.0, 2.0])
SIGMA = np.array([1.0, 1.2, 0.8, 1.5])


def _draws(rng, mean, sigma=SIGMA, counts=COUNTS, steps=STEPS, n=1):
    return pooling.pooled_means(rng, np.tile(mean, (n, 1)), np.tile(sigma, (n, 1)), counts, steps)


@pytest.mark.parametrize("ratio", [0.3, 2.0])
def test_given_omega_the_draws_are_the_gaussian_posterior(monkeypatch, ratio):
    """With ω fixed, μ's posterior under μ = Xb + δ (b flat, δ ~ N(0, ω²I)) and x̄ ~ N(μ, D)
    is Normal(Λ⁻¹D⁻¹x̄, Λ⁻¹), Λ = D⁻¹ + ω⁻²(I − X(XᵀX)⁻¹Xᵀ): the flat line integrates out
    to a prior precision on the residuals from the unweighted least-squares line."""
    monkeypatch.setattr(pooling, "RANGE", (ratio, ratio))
    mean = np.array([0.5, 3.0, 2.0, 7.0])
    se_sq = SIGMA ** 2 / COUNTS
    omega_sq = ratio ** 2 * np.mean(se_sq)
    X = np.column_stack([np.ones(4), STEPS])
    prior_prec = (np.eye(4) - X @ np.linalg.solve(X.T @ X, X.T)) / omega_sq
    cov = np.linalg.inv(np.diag(1 / se_sq) + prior_prec)
    centre = cov @ (mean / se_sq)
    n = 50_000
    draws = _draws(np.random.default_rng(1), mean, n=n)
    se = np.sqrt(np.diag(cov) / n)
    assert np.all(np.abs(draws.mean(axis=0) - centre) < 5 * se), (draws.mean(axis=0), centre)
    np.testing.assert_allclose(np.cov(draws.T), cov, atol=0.02 * np.max(np.diag(cov)))


def test_omega_marginal_is_the_likelihood_integrated_over_the_line():
    """p(x̄ | ω) ∝ ∫∫ N(x̄; Xb, D + ω²I) db, by quadrature over the line's (intercept,
    slope), against the closed form's ratios at four ω."""
    mean = np.array([[0.5, 3.0, 2.0, 7.0]])
    se_sq = (SIGMA ** 2 / COUNTS)[None, :]
    omega_sq = np.array([[0.05, 0.5, 2.0, 8.0]])
    logp, _, _ = pooling.omega_log_posterior(mean, se_sq, STEPS, omega_sq)
    X = pooling._line_design(STEPS)
    a = np.linspace(-30, 30, 1201)
    s = np.linspace(-40, 50, 1801)
    A, B = np.meshgrid(a, s, indexing="ij")
    numeric = []
    for o2 in omega_sq[0]:
        v = se_sq[0] + o2
        fit = A[..., None] * X[:, 0] + B[..., None] * X[:, 1]
        dens = np.exp(-0.5 * np.sum((mean[0] - fit) ** 2 / v, axis=-1)) / np.sqrt(np.prod(2 * np.pi * v))
        numeric.append(np.log(dens.sum() * (a[1] - a[0]) * (s[1] - s[0])))
    numeric = np.array(numeric)
    np.testing.assert_allclose(logp[0] - logp[0, 0], numeric - numeric[0], atol=1e-6)


NODES = np.geomspace(*pooling.RANGE, pooling.NODES)


def _simulate_at_nodes(rng):
    """ω from its prior nodes, the line from a prior much wider than the data (the fit's is flat)."""
    sigma = SIGMA * rng.uniform(0.5, 2.0)
    scale = np.sqrt(np.mean(sigma ** 2 / COUNTS))
    omega = scale * rng.choice(NODES)
    b = rng.normal(0.0, 1e3 * scale, size=2)
    mu = pooling._line_design(STEPS) @ b + omega * rng.standard_normal(4)
    xbar = mu + np.sqrt(sigma ** 2 / COUNTS) * rng.standard_normal(4)
    return {f"mu{c}": mu[c] for c in range(4)} | {"gap01": mu[1] - mu[0]}, (xbar, sigma)


def _fit(data, rng, n=99):
    xbar, sigma = data
    d = _draws(rng, xbar, sigma, n=n)
    return {f"mu{c}": d[:, c] for c in range(4)} | {"gap01": d[:, 1] - d[:, 0]}


def test_sbc_ranks_uniform():
    res = run_sbc(_simulate_at_nodes, _fit, n_datasets=400, seed=3)
    assert res.failed() == [], res.failed()


def test_sbc_catches_a_prior_that_forces_the_line(monkeypatch):
    """The check has power: draws that always put the means on the line (ω at the lowest
    node) fail it. (The flat model's draws would pass: x̄_c − μ_c ~ N(0, σ_c²/n_c) whatever
    the prior, so its marginal intervals for each mean hold; what pooling changes is how
    far apart the cells are believed to be, which decides the plate probabilities.)"""
    monkeypatch.setattr(pooling, "RANGE", (0.05, 0.05))
    assert run_sbc(_simulate_at_nodes, _fit, n_datasets=400, seed=3).failed() != []


def test_limits():
    rng = np.random.default_rng(2)
    se = np.sqrt(SIGMA ** 2 / COUNTS)
    # means far off any line: the data pick the largest ω, and the draws are the flat model's
    zigzag = np.array([0.0, 40.0, -40.0, 40.0])
    d = _draws(rng, zigzag, n=40_000)
    np.testing.assert_allclose(d.mean(axis=0), zigzag, atol=0.05)
    np.testing.assert_allclose(d.std(axis=0), se, rtol=0.05)
    # two cells: no scatter about a line to learn from, the flat model's draws
    d2 = pooling.pooled_means(rng, np.tile([1.0, 5.0], (40_000, 1)), np.tile([1.0, 1.0], (40_000, 1)),
                              np.array([4.0, 4.0]), np.array([0.0, 0.03]))
    np.testing.assert_allclose(d2.std(axis=0), [0.5, 0.5], rtol=0.05)
    # means on a line: pulled onto it, tighter than the flat model
    on_line = 1.0 + 50.0 * STEPS
    d3 = _draws(rng, on_line, n=40_000)
    np.testing.assert_allclose(d3.mean(axis=0), on_line, atol=0.05)
    assert np.all(d3.std(axis=0) < se)
    # a floor plate (step 0) off the risers' line keeps its own mean and spread; the risers are pooled
    floor = np.array([0.0, 0.01, 0.02, 0.03, 0.06])
    means = np.concatenate([[5.0], 1.0 + 50.0 * STEPS])
    d4 = pooling.pooled_means(rng, np.tile(means, (40_000, 1)), np.tile(np.r_[1.0, SIGMA], (40_000, 1)),
                              np.r_[4.0, COUNTS], floor)
    np.testing.assert_allclose(d4.mean(axis=0), means, atol=0.05)
    assert d4[:, 0].std() == pytest.approx(0.5, rel=0.05) and np.all(d4[:, 1:].std(axis=0) < se)


def test_a_modes_cells_that_sit_together_are_drawn_together():
    """Rides on four plates with one mean, snaps rising with the step: the pooled ride
    means of the inner plates scatter less about the outer ones than the flat means do
    (in units of P; the ends' difference is the line's slope, as uncertain as before),
    and the snaps' rise from the first plate to the last is kept."""
    rng = np.random.default_rng(4)
    steps = np.array([0.01, 0.02, 0.03, 0.05])
    group = np.repeat(np.arange(4), 8)
    snap = np.tile([False] * 4 + [True] * 4, 4)
    plates = Plates(steps_mm=steps, group=group, counts=np.bincount(group), snap=snap)
    peak = np.where(snap, 1.0 + 40.0 * steps[group], 1.0) + 0.05 * rng.standard_normal(group.size)
    table = PeakTable(log_tau=np.array([0.0, 0.1]), peak=np.column_stack([peak, peak]))
    tau = np.ones(20_000)
    spread, rise = {}, {}
    for p in (True, False):
        o = two_mode_draws(np.random.default_rng(5), tau, table.at(tau), plates, make_priors(table), pooled=p)
        a, h = o["a"][:, None], o["h"][:, None]
        ride = (o["plate_mean_mm"] - o["snap_share"][:, None] * o["plate_snap_mm"] + h) / a        # units of P
        snap_p = ride + o["plate_snap_mm"] / a
        spread[p] = np.std(ride[:, 1:3] - ride[:, :1], axis=0)
        rise[p] = np.median(snap_p[:, 3] - snap_p[:, 0])
    assert np.all(spread[True] < 0.8 * spread[False]), spread
    assert rise[True] == pytest.approx(rise[False], rel=0.05), rise


def test_the_fit_states_the_pooled_prior_only_where_it_holds():
    """The priors a fit prints name the pooling (and the choice of spread curves) for the
    two-mode models under the reference prior, not for the one-mode models nor under a
    proper plate prior (whose means and curves it keeps)."""
    import dataclasses
    from feeler.calib.neuron.model import PlatePrior
    table = PeakTable(log_tau=np.array([0.0, 0.1]), peak=np.ones((6, 2)))
    pri = make_priors(table)
    assert "cell means" in pri.as_text("two-mode-growing") and "cell means" in pri.as_text("two-mode")
    assert "cell means" not in pri.as_text("growing")
    proper = dataclasses.replace(pri, plate=PlatePrior(nu0=4.0, s0_sq=1.0, kappa0=1.0, m0=(0.0, 1.0)))
    assert "cell means" not in proper.as_text("two-mode")
    assert "BIC" in pri.as_text("two-mode")["spreads"] and "spreads" not in pri.as_text("growing")
    assert "spreads" not in proper.as_text("two-mode")             # a proper prior: a curve each, as SBC draws them
