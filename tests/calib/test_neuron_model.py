"""M2 maths: plate statistics, the decoder line, conjugate draws, the leave-one-out score,
the MCMC target, and the decoder's probabilities and belt — each against a reference."""
import warnings

import numpy as np
import pytest
from scipy import integrate, stats

from feeler.calib.neuron.conjugate import draw_plate_parameters, growth_log_density
from feeler.calib.neuron.decoder import DecoderDraws
from feeler.calib.neuron.model import PeakTable, PlatePrior, Plates, decoder_line, plate_stats
from feeler.calib.neuron.target import log_conditional, node_stats
from feeler.calib.neuron.window import continuous_log_density, loo_elpd

def _design(rng, n=6, mu=(1.0, 2.0, 3.2, 5.5), sd=(0.2, 0.3, 0.3, 0.5)):
    plates = Plates.of(np.repeat([0.0, 0.05, 0.1, 0.2], n))
    g = plates.group
    return plates, np.asarray(mu)[g] + np.asarray(sd)[g] * rng.standard_normal(g.size)


def test_plate_stats_and_line_exact():
    plates = Plates.of([0.1, 0.0, 0.1, 0.0, 0.2])
    np.testing.assert_array_equal(plates.steps_mm, [0.0, 0.1, 0.2])
    np.testing.assert_array_equal(plates.counts, [2, 2, 1])
    mean, ss = plate_stats(np.array([3.0, 1.0, 5.0, 2.0, 9.0]), plates)
    np.testing.assert_allclose(mean, [1.5, 4.0, 9.0])
    np.testing.assert_allclose(ss, [0.5, 2.0, 0.0])
    mu = np.array([[1.0, 3.0, 5.0]])                     # μ = (c + h)/a with a = 0.05, h = 0.05
    a, h = decoder_line(mu, Plates.of([0.0, 0.1, 0.2]))
    assert a[0] == pytest.approx(0.05) and h[0] == pytest.approx(0.05)
    a, _ = decoder_line(np.array([[3.0, 2.0, 1.0]]), Plates.of([0.0, 0.1, 0.2]))
    assert np.isnan(a[0])                                # decreasing plates: no gain


@pytest.mark.parametrize("noise", ["constant", "per-plate", "growing"])
def test_conjugate_draws_match_closed_form_moments(noise):
    rng = np.random.default_rng(1)
    plates, p = _design(rng)
    mean, ss = plate_stats(p, plates)
    S = 40000
    par = draw_plate_parameters(rng, np.tile(mean, (S, 1)), np.tile(ss, (S, 1)), plates, noise, PlatePrior(), 3.0)
    r = plates.counts - 1.0
    np.testing.assert_allclose(par["mu"].mean(axis=0), mean, atol=4 * par["sigma"].max() / np.sqrt(6 * S))
    if noise == "per-plate":                             # σ² ~ scaled-inv-χ²(r, SS/r): E σ² = SS/(r − 2)
        np.testing.assert_allclose((par["sigma"] ** 2).mean(axis=0), ss / (r - 2), rtol=0.05)
    elif noise == "constant":
        assert (par["sigma"][:, 0] ** 2).mean() == pytest.approx(ss.sum() / (r.sum() - 2), rel=0.03)
    else:                                                # g's density against a direct 2-D integral
        g = par["growth"]
        lp = lambda v: growth_log_density(np.array([v]), ss[None], r, plates.x, PlatePrior())[0, 0]  # noqa: E731
        z = integrate.quad(lambda v: np.exp(lp(v) - lp(0.0)), -3, 3)[0]
        m1 = integrate.quad(lambda v: v * np.exp(lp(v) - lp(0.0)), -3, 3)[0] / z
        assert g.mean() == pytest.approx(m1, abs=4 * g.std() / np.sqrt(S) + 0.01)

        def joint(v, s0):                               # p(g, σ₀ | data) ∝ likelihood × 1/σ₀
            sig = s0 * np.exp(v * plates.x)
            return np.exp(np.sum(-r * np.log(sig) - ss / (2 * sig ** 2)) - np.log(s0) + 40)
        ref = integrate.dblquad(lambda s0, v: v * joint(v, s0), -3, 3, 0.01, 3)[0] / \
            integrate.dblquad(lambda s0, v: joint(v, s0), -3, 3, 0.01, 3)[0]
        assert m1 == pytest.approx(ref, abs=1e-3)


def test_continuous_density_equals_numerical_integral():
    steps = np.array([0.0, 0.05, 0.1, 0.2])
    mu = np.array([1.0, 2.0, 3.2, 5.5])
    s = np.array([0.4, 0.5, 0.5, 0.8])
    for p, c in ((1.7, 1), (5.0, 3), (0.2, 0)):
        got = continuous_log_density(np.array(p), np.array(c), mu, s, steps)
        # reference: the flat-prior posterior density of δ on a fine grid, curve extended linearly
        grid = np.linspace(-2.0, 2.5, 400001)
        seg = np.clip(np.searchsorted(steps, grid) - 1, 0, 2)
        m = mu[seg] + (grid - steps[seg]) * (mu[seg + 1] - mu[seg]) / (steps[seg + 1] - steps[seg])
        frac = np.clip((grid - steps[seg]) / (steps[seg + 1] - steps[seg]), 0, 1)
        sd = s[seg] + frac * (s[seg + 1] - s[seg])
        dens = stats.norm.pdf(p, m, sd)
        ref = np.log(stats.norm.pdf(p, mu[c], s[c]) / np.trapezoid(dens, grid))
        assert got == pytest.approx(ref, abs=1e-6)
    assert continuous_log_density(np.array(2.0), np.array(1), np.array([1.0, 3.0, 2.0, 4.0]), s, steps) == -np.inf


@pytest.mark.parametrize("p, c", [(1.7, 1), (2.1, 2), (2.0, 1), (5.0, 3), (0.2, 0), (7.0, 3)])
def test_continuous_density_of_a_monotone_curve_with_a_flat_segment_and_end_slopes(p, c):
    """A monotone curve (isotonic regression pools plates: a flat segment) with its own
    slopes past the ends, as the two-mode leave-one-out reads a mode's curve: the density
    equals the flat-prior posterior density of δ on a fine grid."""
    steps = np.array([0.0, 0.05, 0.1, 0.2])
    mu = np.array([1.0, 2.0, 2.0, 5.5])
    s = np.array([0.4, 0.5, 0.7, 0.8])
    ends = np.array([25.0, 3.0])
    got = continuous_log_density(np.array(p), np.array(c), mu, s, steps, ends)
    grid = np.linspace(-4.0, 6.0, 1000001)
    seg = np.clip(np.searchsorted(steps, grid) - 1, 0, 2)
    m = mu[seg] + (grid - steps[seg]) * (mu[seg + 1] - mu[seg]) / (steps[seg + 1] - steps[seg])
    m = np.where(grid < steps[0], mu[0] + (grid - steps[0]) * ends[0], m)
    m = np.where(grid > steps[-1], mu[-1] + (grid - steps[-1]) * ends[1], m)
    frac = np.clip((grid - steps[seg]) / (steps[seg + 1] - steps[seg]), 0, 1)
    sd = s[seg] + frac * (s[seg + 1] - s[seg])
    ref = np.log(stats.norm.pdf(p, mu[c], s[c]) / np.trapezoid(stats.norm.pdf(p, m, sd), grid))
    assert got == pytest.approx(ref, abs=1e-6)
    assert continuous_log_density(np.array(p), np.array(c), mu, s, steps, np.array([25.0, 0.0])) == -np.inf


def test_loo_elpd_equals_refitting_without_each_scan():
    rng = np.random.default_rng(2)
    plates, p = _design(rng, n=5)
    table = PeakTable(log_tau=np.log([1.0, 2.0]), peak=np.column_stack([p, 1.3 * p + 0.1]))
    got = loo_elpd(table, plates, "per-plate")
    for j in range(2):
        ref = 0.0
        for k in range(p.size):
            keep = np.arange(p.size) != k
            pk = Plates.of(plates.steps_mm[plates.group[keep]])
            mean, ss = plate_stats(table.peak[keep, j], pk)
            s = np.sqrt(ss / (pk.counts - 1) * (1 + 1 / pk.counts))
            ref += continuous_log_density(np.array(table.peak[k, j]), np.array(plates.group[k]), mean, s,
                                          plates.steps_mm)
        assert got[j] == pytest.approx(ref, rel=1e-10)


@pytest.mark.parametrize("noise", ["per-plate", "growing"])
def test_loo_elpd_in_blocks_of_scans_equals_all_at_once(monkeypatch, noise):
    """loo_elpd holds the quadrature of a block of scans at a time (2000 scans at once
    peaked at 1.56 GB in `calibrate neuron`); per element the numbers are the same."""
    import feeler.calib.neuron.window as window

    rng = np.random.default_rng(3)
    plates, p = _design(rng, n=7)
    table = PeakTable(log_tau=np.log([1.0, 2.0, 4.0]), peak=np.column_stack([p, 1.3 * p + 0.1, 0.8 * p]))
    whole = loo_elpd(table, plates, noise, pointwise=True)
    for nodes in (1.0, 3 * 3 * 24 * 5.0):              # one scan, then five (3 nodes × 3 segments × 24), per block
        monkeypatch.setattr(window, "_QUADRATURE_BLOCK", nodes)
        np.testing.assert_array_equal(loo_elpd(table, plates, noise, pointwise=True), whole)


@pytest.mark.parametrize("noise, k", [("per-plate", 4), ("constant", 1), ("growing", 2)])
def test_mcmc_target_is_a_normalised_density(noise, k):
    """log_conditional integrates to 1 over (m, spreads) — checked by importance sampling
    from the exact backend's draws (the ratio of densities must average 1)."""
    rng = np.random.default_rng(3)
    plates, p = _design(rng)
    table = PeakTable(log_tau=np.log([1.0, 1.0 + 1e-9]), peak=np.column_stack([p, p]))
    st = node_stats(table, plates, np.log([1.0]), np.zeros(1), noise)
    # proposal: wide normal around the sample statistics in mm
    zbar, q = st.zbar[0], st.q[0]
    sd0 = np.sqrt(q / plates.counts)
    centre = np.concatenate([zbar, np.log(np.sqrt(q / (plates.counts - 1)))[:k] if noise != "growing"
                             else [np.log(np.sqrt(q.sum() / 20)), 0.0]])
    scale = np.concatenate([3 * sd0 / np.sqrt(plates.counts), np.full(k, 0.6)])
    n = 400000
    x = centre + scale * rng.standard_normal((n, centre.size))
    if noise == "growing":
        x = x[np.abs(x[:, -1]) <= 3.0]
    logq = np.sum(stats.norm.logpdf(x, centre, scale), axis=1)
    lp = log_conditional(x[:, :4], x[:, 4:], zbar, q, st.k[0], plates, noise)
    w = np.exp(lp - logq)
    total = w.sum() / n
    assert total == pytest.approx(1.0, rel=0.03)


def _fixed(mean_mm, sd_mm, a=2.0, h=0.1, tau=3.0, steps=(0.0, 0.05, 0.1, 0.2)):
    mean_mm, sd_mm = np.atleast_2d(mean_mm), np.atleast_2d(sd_mm)
    S = mean_mm.shape[0]
    return DecoderDraws(np.asarray(steps), np.full(S, tau), np.full(S, a), np.full(S, h), mean_mm, sd_mm)


def test_class_probabilities_by_bayes_rule():
    dec = _fixed([0.003, 0.05, 0.1, 0.2], [0.004, 0.005, 0.006, 0.008])
    p = np.array([[0.04, 0.06, 0.2]])                        # P at τ; z = 2P − 0.1
    z = 2 * p[0] - 0.1
    dens = np.array([stats.norm.pdf(z, m, s) for m, s in zip(dec.mean_mm[0], dec.sd_mm[0])]).T
    np.testing.assert_allclose(np.exp(dec.class_log_prob(p)), dens / dens.sum(axis=1, keepdims=True), rtol=1e-10)


def test_height_belt_on_a_straight_curve_is_z_plus_minus_1645_sd():
    steps = (0.0, 0.1, 0.2)
    dec = _fixed([0.0, 0.1, 0.2], [0.01, 0.01, 0.01], a=1.0, h=0.0, steps=steps)
    z = np.array([[0.05, 0.13, 0.5]])
    est, lo, hi = dec.height(z)
    np.testing.assert_allclose(est, z[0], atol=1e-9)
    np.testing.assert_allclose(lo, z[0] - stats.norm.ppf(0.95) * 0.01, atol=1e-9)
    np.testing.assert_allclose(hi, z[0] + stats.norm.ppf(0.95) * 0.01, atol=1e-9)
    low = dec.height(np.array([[-0.01]]))                   # below the flat plate: clipped at 0, 0 covered
    assert low[1][0] == 0.0 and low[0][0] == 0.0 and low[2][0] > 0


def test_draws_whose_top_plates_reverse_do_not_turn_the_belt_back():
    """With six touches a plate 1-28 % of a fit's draws have two plates' means reversed
    (hard/six-plates-few, ten training sets; 0.4-26 % at an end segment).
    Where that was the top segment, the curve ran downwards past the top plate, F turned
    back up towards the reversed draws' share (15 % here, over the 5 % level) and the
    bisection returned the edge of its bracket: an upper bound of ~10¹³ mm, which covered
    every step (measured on hard/six-plates-few: 8·10¹² mm). Each draw's curve is now
    isotonic ([0, 0.2, 0.1] → [0, 0.15, 0.15]) with its end slopes at least a tenth of its
    mean slope (here 0.075), so F falls throughout and the bounds solve the belt."""
    sd, steps = 0.01, (0.0, 0.1, 0.2)
    means = np.array([[0.0, 0.1, 0.2]] * 85 + [[0.0, 0.2, 0.1]] * 15)
    dec = _fixed(means, np.full(means.shape, sd), a=1.0, h=0.0, steps=steps)
    z = np.array([[0.2, 0.21, 0.1]])
    est, lo, hi = dec.height(z)
    # the reversed draws' flat top, extrapolated at 0.075: F = 0.05 where their 15 % share
    # is a third: m = 0.15 + 0.075 (δ − 0.2) = z + Φ⁻¹(2/3)·sd, the others' Φ being ~0
    expect = 0.2 + (z[0, :2] + stats.norm.ppf(2 / 3) * sd - 0.15) / 0.075
    np.testing.assert_allclose(hi[:2], expect, rtol=1e-3)
    grid = np.linspace(-0.5, 3.0, 701)
    f = dec.predictive_cdf(np.repeat(z, grid.size, axis=1), np.tile(grid, 3))         # a = 1, h = 0: z = P
    assert np.all(np.diff(f.reshape(3, -1), axis=1) <= 1e-12)                  # non-increasing in δ
    np.testing.assert_allclose(dec.predictive_cdf(z, hi), 0.05, atol=1e-6)
    np.testing.assert_allclose(dec.predictive_cdf(z, lo), 0.95, atol=1e-6)
    assert np.all((lo <= est) & (est <= hi))


def test_height_belt_at_the_floor_is_one_sided_and_holds_90_percent_at_every_step():
    """No step lies below 0, so at δ = 0 the band keeps every reading below its 90 %
    quantile (one-sided), turning central over two sds: 0 is inside the interval exactly
    when z ≤ m₀ + 1.2816·s₀, and at every true step near and away from the floor 90 % of
    readings give an interval holding it (the clipped central belt held 95 % at δ = 0)."""
    sd = 0.01
    dec = _fixed([0.0, 0.1, 0.2], [sd] * 3, a=1.0, h=0.0, steps=(0.0, 0.1, 0.2))
    q90 = stats.norm.ppf(0.9) * sd
    _, lo, hi = dec.height(np.array([[-0.03, 0.0, q90 - 1e-7, q90 + 1e-7, 0.03]]))
    np.testing.assert_array_equal(lo[:3], 0.0)
    assert np.all(lo[3:] > 0) and np.all(hi > lo)
    rng = np.random.default_rng(4)
    n = 20000
    for delta in (0.0, 0.005, 0.01, 0.02, 0.05, 0.1):
        z = delta + sd * rng.standard_normal((1, n))
        _, lo, hi = dec.height(z)
        cover = np.mean((lo <= delta) & (delta <= hi))
        assert abs(cover - 0.9) < 3 * np.sqrt(0.09 / n), (delta, cover)


def test_continuous_density_of_a_plate_with_no_spread_warns_nothing():
    """A degenerate training set (labels reversed, a flat noisy U_y: an outside audit) gave
    plates a spread near 0; the tails' ratios overflowed and "overflow encountered in divide"
    reached the user twice. The density is −inf or finite there, silently."""
    p = np.array([0.5, 1e10, -1e10])
    mu, s = np.array([[0.0, 1.0]] * 3), np.full((3, 2), 1e-300)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        out = continuous_log_density(p, np.zeros(3, int), mu, s, np.array([0.0, 0.1]))
    assert out.shape == (3,) and not np.any(np.isnan(out))
