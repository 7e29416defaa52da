"""The exact backend: against a brute-force integral, invariances, estimands, nAFC, pc."""
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.stats import beta as beta_dist
from scipy.stats import norm

from feeler.calib.psychometric.fit import fit_psychometric, threshold_table
from feeler.calib.psychometric.model.task import Task
from feeler.psydata import KEY_COLUMNS, TRIAL_COLUMNS

LEVELS = np.array([7.6, 8.4, 9.2, 10.0, 10.8, 11.6, 12.4])


def _one(k, n=40, subject="A") -> pd.DataFrame:
    return pd.DataFrame([(subject, 10.0, 20.0, x, 20.0, n, int(kk)) for x, kk in zip(LEVELS, k)],
                        columns=list(TRIAL_COLUMNS))


def _brute_force(k, n, pc, pse_range):
    """The posterior on a dense uniform grid over (PSE, log σ, λ) with the default priors
    written out by hand (range 4.8 µm: PSE ~ N(10, 2.4), log σ ~ N(log 1.2, 1), λ = B/2)."""
    pse, log_sig, lam = np.linspace(*pse_range, 241), np.linspace(np.log(0.02), np.log(60.0), 201), \
        np.linspace(1e-6, 0.45, 61)
    p_, ls_, l_ = np.meshgrid(pse, log_sig, lam, indexing="ij", sparse=True)
    s_ = np.exp(ls_)
    lp = norm.logpdf(p_, 10.0, 2.4) + norm.logpdf(ls_, np.log(1.2), 1.0) + beta_dist.logpdf(l_ / 0.5, 2, 18)
    for x, kk in zip(LEVELS, k):
        phi = norm.cdf((x - p_) / s_)
        lp = lp + kk * np.log(l_ / 2 + (1 - l_) * phi) + (n - kk) * np.log(l_ / 2 + (1 - l_) * (1 - phi))
    w = np.exp(lp - lp.max())
    w /= w.sum()
    assert w[:, -1, :].sum() < 1e-6 and w[0].sum() < 1e-6 and w[-1].sum() < 1e-6   # grid holds it
    p_, s_, l_ = np.broadcast_arrays(p_, s_, l_)
    q = lambda p: norm.ppf((p - l_ / 2) / (1 - l_))
    values = {"pse": p_, "dt": s_ * q(0.75), "threshold": p_ + s_ * q(pc),
              "slope": (1 - l_) * norm.pdf(q(pc)) / s_}
    out = {}
    for name, v in values.items():
        ok = np.isfinite(v)                          # P never reaches pc: negligible mass here
        assert w[~ok].sum() < 1e-4
        vv, inverse = np.unique(v[ok], return_inverse=True)           # ties (grid axes) merged
        ww = np.bincount(inverse.ravel(), weights=w[ok])
        out[name] = (float((w[ok] * v[ok]).sum() / ww.sum()), *np.interp([0.025, 0.975], np.cumsum(ww) - ww / 2, vv))
    return out


@pytest.mark.parametrize("seed, n", [(0, 40), (4, 6)])
def test_summaries_match_a_brute_force_integral(seed, n):
    """Mean and 95 % bounds of PSE, DT, threshold and slope at pc = 0.85 within 1 % of the
    interval width (the brute-force grid's own resolution is a few tenths of a percent);
    n = 6 trials per level gives skewed tails."""
    rng = np.random.default_rng(seed)
    k = rng.binomial(n, Task().p(LEVELS, 10.2, 1.1, 0.04))
    row = threshold_table(fit_psychometric(_one(k, n), rng=np.random.default_rng(0), pc=0.85)).iloc[0]
    half = 4 * (row.pse_ub_um - row.pse_lb_um)                 # the brute force checks it holds the mass
    ref = _brute_force(k, n, 0.85, (row.pse_um - half, row.pse_um + half))
    for name, unit in (("pse", "_um"), ("dt", "_um"), ("threshold", "_um"), ("slope", "_per_um")):
        got = np.array([row[f"{name}{unit}"], row[f"{name}_lb{unit}"], row[f"{name}_ub{unit}"]])
        width = got[2] - got[1]
        np.testing.assert_allclose(got, ref[name], atol=0.01 * width, err_msg=name)


def test_row_order_and_zero_rows_change_nothing_but_rounding(simulate):
    trials, _ = simulate(31, n_subjects=3)
    padded = pd.concat([trials.sample(frac=1.0, random_state=1),
                        trials.iloc[:4].assign(n_trials=0, n_comparison_higher=0)])
    padded = padded.sort_values("subject", kind="stable")            # subjects keep their order
    a = fit_psychometric(trials, rng=np.random.default_rng(3), draws=200)
    b = fit_psychometric(padded, rng=np.random.default_rng(3), draws=200)
    pd.testing.assert_frame_equal(threshold_table(a), threshold_table(b), check_exact=False, rtol=1e-12)
    np.testing.assert_allclose(a.posterior["posterior"]["pse"].values, b.posterior["posterior"]["pse"].values,
                               rtol=1e-12)


def test_one_subjects_all_is_that_subject(simulate):
    trials, _ = simulate(5, n_subjects=1)
    table = threshold_table(fit_psychometric(trials, rng=np.random.default_rng(0), draws=200))
    numbers = table.select_dtypes("number")
    subject, pooled = numbers[table.subject == "S1"], numbers[table.subject == "all"]
    np.testing.assert_array_equal(subject.to_numpy(), pooled.to_numpy())
    assert set(table[table.subject == "all"].estimand) == {"pooled trials"}


def test_lapse_per_condition_equals_per_subject_for_one_condition():
    k = np.random.default_rng(2).binomial(30, Task().p(LEVELS, 9.8, 1.4, 0.02))
    a = threshold_table(fit_psychometric(_one(k, 30), rng=np.random.default_rng(0), draws=100))
    b = threshold_table(fit_psychometric(_one(k, 30), rng=np.random.default_rng(0), draws=100, lapse_per="condition"))
    cols = ["pse_um", "pse_lb_um", "dt_um", "dt_ub_um", "threshold_um", "lapse", "pse_map_um", "dt_map_um"]
    np.testing.assert_allclose(a[cols].to_numpy(), b[cols].to_numpy(), rtol=2e-4)


def test_nafc_recovers_a_detection_threshold():
    task, rng = Task(4), np.random.default_rng(7)
    x = np.array([0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0])
    k = rng.binomial(200, task.p(x, 1.9, 0.6, 0.02))
    trials = pd.DataFrame([("A", 0.0, 20.0, xi, 20.0, 200, int(kk)) for xi, kk in zip(x, k)],
                          columns=list(KEY_COLUMNS) + ["n_trials", "n_correct"])
    result = fit_psychometric(trials, rng=np.random.default_rng(0), nafc=4, draws=300)
    row = threshold_table(result).iloc[0]
    truth = float(task.x_at(0.625, 1.9, 0.6, 0.02))
    assert result.verdict.ok and row.pc == 0.625 and row.design == "4AFC"
    assert row.threshold_lb_um < truth < row.threshold_ub_um and row.pse_lb_um < 1.9 < row.pse_ub_um


def test_a_proportion_beyond_the_lapse_is_reported_as_unreached():
    k = np.random.default_rng(1).binomial(10, Task().p(LEVELS, 10.0, 1.0, 0.2))
    row = threshold_table(fit_psychometric(_one(k, 10), rng=np.random.default_rng(0), pc=0.97,
                                           draws=200)).iloc[0]
    assert 0.025 < row.threshold_unreached < 1 and np.isnan(row.threshold_um) and np.isinf(row.threshold_ub_um)
    assert np.isfinite(row.threshold_lb_um)


def test_a_broad_spread_posterior_has_its_quantiles_where_its_draws_are():
    """One tested level leaves σ's posterior broad (the grid spans 10⁻³-10⁶ µm); its table
    quantiles (searched in log space) agree with the posterior draws' and hold the mean:
    searched linearly, the median came out 10.0 µm and the interval [0.50, 19.6] µm
    around a mean of 0.84 µm."""
    trials = pd.DataFrame({"subject": ["S1"], "standard_um": [10.0], "standard_speed_mm_s": [20.0],
                           "comparison_um": [10.8], "comparison_speed_mm_s": [20.0], "n_trials": [40],
                           "n_comparison_higher": [30]})
    res = fit_psychometric(trials, rng=np.random.default_rng(0))
    row = threshold_table(res).iloc[0]
    for name in ("sigma", "dt"):
        draws = res.posterior["posterior"][name].values.ravel()
        lb, med, ub = (row[f"{name}{k}_um"] for k in ("_lb", "_median", "_ub"))
        assert lb <= row[f"{name}_um"] <= ub
        np.testing.assert_allclose([lb, med, ub], np.quantile(draws, [0.025, 0.5, 0.975]), rtol=0.12)


def test_independent_draws_are_not_failed_by_r_hat_noise(simulate):
    """The exact grid's draws are independent: R-hat has nothing to detect there, and at 4
    chains of 100 draws its noise alone read above 1.01 for about 1 parameter in 9."""
    from feeler.calib.fit import DiagnosticWarning

    trials, _ = simulate(7, n_subjects=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DiagnosticWarning)
        result = fit_psychometric(trials, rng=np.random.default_rng(11), chains=4, draws=100)
    assert (result.summary["r_hat"] > 1.01).any()              # the noise is there, shown in the table
    assert not [p for p in result.verdict.problems if "R-hat" in p or "ESS" in p], result.verdict.problems


@pytest.mark.parametrize("chains, draws, match", [(1, 5, "chains=1: at least 2"), (1, 1000, "chains=1"),
                                                  (4, 50, "draws=50: at least 100 with 4 chains")])
def test_too_few_chains_or_draws_are_refused_with_the_minimum(chains, draws, match):
    from feeler.errors import ArgumentError

    with pytest.raises(ArgumentError, match=match):
        fit_psychometric(_one([2, 5, 10, 20, 30, 35, 38]), rng=np.random.default_rng(0), chains=chains, draws=draws)
