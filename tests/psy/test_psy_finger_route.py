"""The finger route: skin L0 → neuron → observer → binomial, τ and σ_d on a grid."""
import numpy as np
import pandas as pd
import pytest

from feeler.calib.psychometric.finger_route import (RouteGrid, _edge_problems, accepted_heights,
                                       fit_finger_route, lapse_density, paper_verdict, predict_p_higher,
                                       tau_report)
from feeler.calib.fit import DiagnosticWarning
from feeler.calib.psychometric.outputs.checks import speed_problems
from feeler.errors import ArgumentError

GRID = RouteGrid(n_tau=81, n_sigma=50, n_lapse=5)


@pytest.fixture(scope="module")
def design(simulate):
    trials, _ = simulate(0, n_subjects=6, n_trials=20)
    return trials


def test_kappa_makes_the_mean_slope_one():
    heights = (5.0, 7.5, 10.0, 12.5, 15.0)
    stim = [(h, v) for v in (20.0, 40.0) for h in heights]
    s_hat, kappa = accepted_heights(stim, np.array([0.01, 0.1, 1.0]))
    slopes = s_hat.reshape(3, 2, 5) / np.array(heights)       # L0 is linear in the height
    np.testing.assert_allclose(slopes.std(axis=2), 0.0, atol=1e-9)
    np.testing.assert_allclose(slopes[:, :, 0].mean(axis=1), 1.0, rtol=1e-12)
    assert np.all(slopes[:, 1, 0] >= slopes[:, 0, 0] - 1e-12)  # felt higher at 40 mm/s
    assert slopes[2, 1, 0] == pytest.approx(slopes[2, 0, 0], rel=1e-3)  # τ ≫ slide: no speed effect


def test_the_lapse_density_is_the_prior_reweighted_per_node_cell():
    """Draws on the lapse nodes as a density: node k's share times n times the prior over
    its cell (the prior's k/n to (k+1)/n quantiles), integrating to 1."""
    from scipy.stats import beta

    edges, nodes = GRID.lapse_edges(), GRID.lapses()
    assert edges[0] == 0.0 and edges[-1] == 0.5 and np.all((edges[:-1] < nodes) & (nodes < edges[1:]))
    draws = np.repeat(nodes, [1, 2, 3, 0, 4])                  # shares 0.1, 0.2, 0.3, 0, 0.4
    x = np.linspace(0.0, 0.5, 200_001)
    f = lapse_density(GRID, draws, x)
    assert np.sum(f) * (x[1] - x[0]) == pytest.approx(1.0, abs=1e-4)
    prior = beta.pdf(x / 0.5, GRID.lapse_a, GRID.lapse_b) / 0.5
    cell = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, 4)
    np.testing.assert_allclose(f, prior * 5 * np.array([0.1, 0.2, 0.3, 0.0, 0.4])[cell])
    np.testing.assert_allclose(lapse_density(GRID, nodes, x), prior)          # one draw per node: the prior


def test_predicted_probabilities(design):
    p = predict_p_higher(design, tau_s=0.1, sigma_d_um=1.0, lapse=0.0)
    same = (design.standard_speed_mm_s == 20.0) & (design.comparison_um == 10.0)
    np.testing.assert_allclose(p[same.to_numpy()], 0.5, atol=1e-12)
    faster = (design.standard_speed_mm_s == 40.0) & (design.comparison_um == 10.0)
    assert np.all(p[faster.to_numpy()] < 0.5)                 # the 40 mm/s standard feels higher
    first = design[design.subject == "S1"].index
    for v in (20.0, 40.0):
        sel = (design.loc[first].standard_speed_mm_s == v).to_numpy()
        assert np.all(np.diff(p[first][sel]) > 0)


def test_recovers_tau_and_noise_from_data_simulated_by_the_chain(design):
    hits = 0
    for seed, tau in enumerate((0.03, 0.1, 0.2, 0.1)):
        rng = np.random.default_rng(40 + seed)
        p = predict_p_higher(design, tau_s=tau, sigma_d_um=1.2, lapse=0.02)
        data = design.assign(n_comparison_higher=rng.binomial(design.n_trials, p))
        result = fit_finger_route(data, rng=rng, grid=GRID, draws=500)
        s = result.summary.set_index("name")
        hits += int(s.loc["tau_s", "eti95_lb"] <= tau <= s.loc["tau_s", "eti95_ub"])
        hits += int(s.loc["sigma_d_um", "eti95_lb"] <= 1.2 <= s.loc["sigma_d_um", "eti95_ub"])
        report = tau_report(result)
        assert report["tau_eti95_s"][0] <= report["tau_median_s"] <= report["tau_eti95_s"][1]
        draws = result.posterior["posterior"]["tau_s"].values.ravel()   # jittered over the same cells
        assert report["tau_mean_s"] == pytest.approx(draws.mean(), abs=4 * draws.std() / np.sqrt(draws.size))
    assert hits >= 7


def test_shipped_like_data_fit_and_report(design, extreme):
    result = fit_finger_route(design, rng=np.random.default_rng(1), grid=GRID, draws=400)
    assert result.verdict.ok, result.verdict.problems
    report = tau_report(result)
    assert 0.0 <= report["p_tau_le_300ms"] <= 1.0 and report["skin_level"] == "l0"
    assert report["paper"] == paper_verdict(report["p_tau_le_300ms"])
    assert set(result.priors) == {"tau_s", "sigma_d_um", "lapse", "kappa"}        # every parameter has its prior
    assert "derived" in result.priors["kappa"] and "5, 7.5, 10, 12.5, 15 µm" in result.priors["kappa"]
    # extremes: all-correct and all-wrong conditions, zero-trial rows, one subject
    with pytest.warns(DiagnosticWarning, match="sigma_d_um: posterior piles against its upper"):
        result = fit_finger_route(extreme, rng=np.random.default_rng(2), grid=GRID, draws=400)
    assert np.all(np.isfinite(result.summary["mean"])) and not result.verdict.ok


def test_zero_trial_rows_change_nothing(design):
    padded = pd.concat([design, design.iloc[:4].assign(n_trials=0, n_comparison_higher=0)])
    a = fit_finger_route(design, rng=np.random.default_rng(3), grid=GRID, draws=200)
    b = fit_finger_route(padded, rng=np.random.default_rng(3), grid=GRID, draws=200)
    assert tau_report(a) == tau_report(b)


def test_edge_piling_is_flagged():
    taus, sigmas = np.geomspace(1e-3, 10, 10), np.geomspace(0.1, 10, 8)
    prob = np.zeros((10, 8, 2))
    prob[4, 3, :] = 0.5
    assert _edge_problems(prob, taus, sigmas) == []
    prob[9, 3, 0] = 0.2
    prob /= prob.sum()
    problems = _edge_problems(prob, taus, sigmas)
    assert len(problems) == 1 and problems[0].startswith("tau_s: posterior piles against its upper")


def test_one_speed_pair_does_not_pin_tau(design):
    """κ(τ) calibrates the accepted height at each speed, so τ shows only in how the
    judgements change with the speed. The trials at equal speeds alone gave the prior
    back (mean 1.1 s, [1.2, 8238] ms) with a verdict of ok."""
    same = design[design.standard_speed_mm_s == design.comparison_speed_mm_s]
    result = fit_finger_route(same, rng=np.random.default_rng(4), grid=GRID, draws=200)
    (line,) = [p for p in result.verdict.problems if p.startswith("tau_s: not pinned")]
    assert "the speed pair(s) 20/20 mm/s" in line
    both = fit_finger_route(design, rng=np.random.default_rng(4), grid=GRID, draws=200)
    assert not any("not pinned" in p for p in both.verdict.problems)


@pytest.mark.parametrize("kwargs", [dict(tau_min_s=0.0), dict(sigma_d_min_um=30.0),
                                    dict(n_lapse=1), dict(lapse_a=0.0), dict(kappa_heights_um=())])
def test_bad_grid(kwargs):
    with pytest.raises(ArgumentError):
        RouteGrid(**kwargs)


@pytest.mark.parametrize("p, words", [(0.999, "these data agree"), (0.95, "these data agree"),
                                      (0.5, "these data cannot tell"), (0.05, "these data contradict it"),
                                      (0.001, "these data contradict it")])
def test_the_paper_line_is_worded_from_the_probability(p, words):
    text = paper_verdict(p)
    assert words in text and f"P(tau <= 300 ms | data) = {p:.3f}" in text and "coincide" not in text


def test_speeds_in_metres_per_second_are_named(design):
    """The chain simulates the skin at the table's speeds: given in m/s (0.02, 0.04) τ piled
    against the grid's 10 s bound and the verdict named no cause."""
    slow = design.assign(standard_speed_mm_s=design.standard_speed_mm_s / 1000,
                         comparison_speed_mm_s=design.comparison_speed_mm_s / 1000)
    with pytest.warns(DiagnosticWarning):
        result = fit_finger_route(slow, rng=np.random.default_rng(5), grid=GRID, draws=200)
    assert result.verdict.problems[0] == ("speeds: the scan speeds 0.02–0.04 'mm/s' (median 0.02) are below a "
                                          "fingertip's (1–1000 mm/s): were they given in m/s (× 1000 → 20–40 mm/s)?")
    assert speed_problems(np.array([20.0, 40.0])) == []
    # above the window both slips bring it back: each is named with what it gives
    assert speed_problems(np.array([2e4, 4e4])) == [
        "speeds: the scan speeds 2e+04–4e+04 'mm/s' (median 3e+04) are above a fingertip's (1–1000 mm/s): were they "
        "given in mm/min, a stage's feed-rate unit (÷ 60 → 333.3–666.7 mm/s) or in µm/s (÷ 1000 → 20–40 mm/s)?"]
    assert speed_problems(np.array([1200.0, 2400.0])) == [
        "speeds: the scan speeds 1200–2400 'mm/s' (median 1.8e+03) are above a fingertip's (1–1000 mm/s): were they "
        "given in mm/min, a stage's feed-rate unit (÷ 60 → 20–40 mm/s) or in µm/s (÷ 1000 → 1.2–2.4 mm/s)?"]
    assert speed_problems(np.array([np.nan, 5e7])) == [
        "speeds: the scan speeds 5e+07–5e+07 'mm/s' (median 5e+07) are above a fingertip's (1–1000 mm/s)"]


def test_subjects_at_chance_or_always_right_fail_the_pooled_fit(design):
    """S5 at chance at every level and S6 always right were pooled with the others into one
    (τ, σ_d, λ): 'verdict: ok', while fit psychophysics failed naming both."""
    from feeler.calib.psychometric.finger_route import SUBJECT_SIGMA_FACTOR

    right = np.where(design.comparison_um > design.standard_um, design.n_trials,
                     np.where(design.comparison_um < design.standard_um, 0, design.n_trials // 2))
    k = np.where(design.subject == "S5", design.n_trials // 2,
                 np.where(design.subject == "S6", right, design.n_comparison_higher))
    with pytest.warns(DiagnosticWarning, match="subjects: S5"):
        result = fit_finger_route(design.assign(n_comparison_higher=k), rng=np.random.default_rng(6), grid=GRID,
                                  draws=200)
    (line,) = [p for p in result.verdict.problems if p.startswith("subjects:")]
    assert line.startswith("subjects: S5 (no rise, as at chance: sigma_d infinite), S6 (sigma_d ")
    assert f"more than {SUBJECT_SIGMA_FACTOR:g} times apart" in line and "S1" not in line and "\n" not in line
    ok = fit_finger_route(design, rng=np.random.default_rng(6), grid=GRID, draws=200)   # ordinary observers pass
    assert not any(p.startswith("subjects:") for p in ok.verdict.problems)


@pytest.mark.parametrize("chains, draws, name", [(1, 1000, "chains"), (4, 5, "draws"), (2, 199, "draws"),
                                                 (200, 2, "draws")])
def test_too_few_draws_for_r_hat_and_ess_are_refused_first(design, chains, draws, name):
    """--draws 5 --chains 1 printed 'R-hat nan' beside a table of numbers."""
    with pytest.raises(ArgumentError, match=f"argument {name}={draws if name == 'draws' else chains}: .*>= 400"):
        fit_finger_route(design, rng=np.random.default_rng(0), grid=GRID, chains=chains, draws=draws)
