"""M4 with the deterministic Laplace backend (approximate): likelihood, recovery, extremes,
outputs, invariances."""
import warnings

import numpy as np
import pandas as pd
import pytest
from scipy.stats import betabinom, binom

from feeler.calib.fit import load
from feeler.calib.psychometric.model.cells import Priors, log_lik_cells, make_cells
from feeler.calib.psychometric.model.mode import hessian, newton_polish
from feeler.calib.psychometric.fit import (THRESHOLD_COLUMNS, ApproximationWarning, fit_psychometric,
                                           save_psychometric, threshold_table)

pytestmark = pytest.mark.filterwarnings("ignore::feeler.calib.psychometric.fit.ApproximationWarning")
from feeler.errors import ArgumentError, OverwriteError
from feeler.models.psychometric import p_higher


def test_cell_likelihood_matches_scipy(simulate):
    trials, _ = simulate(3, n_subjects=2)
    cells = make_cells(trials)
    pse, sigma, lam = 10.2, 1.4, 0.04
    p = p_higher(cells.x_um, pse, sigma, lam)
    ll = log_lik_cells(cells, pse, sigma, lam)
    np.testing.assert_allclose(ll, binom.logpmf(cells.k, cells.n, p), rtol=1e-10)
    ll = log_lik_cells(cells, pse, sigma, lam, phi=25.0)
    want = betabinom.logpmf(cells.k, cells.n, 25.0 * p, 25.0 * (1 - p))
    np.testing.assert_allclose(ll, want, rtol=1e-9)


def test_zero_trial_cells_contribute_exactly_nothing(extreme):
    cells = make_cells(extreme)
    zero = cells.n == 0
    for phi in (None, 10.0):
        ll = log_lik_cells(cells, 10.0, 0.01, 0.0, phi)     # all-or-none responses, no lapse
        assert np.all(ll[zero] == 0.0) and np.all(np.isfinite(ll[cells.condition == 0]))


def test_hessian_of_a_quadratic_is_exact():
    a = np.array([[3.0, 1.0], [1.0, 2.0]])
    h = hessian(lambda x: 0.5 * np.einsum("bi,ij,bj->b", x, a, x) + x[:, 0], np.array([0.3, -2.0]))
    np.testing.assert_allclose(h, a, rtol=1e-6)


def test_recovery_coverage_over_seeds(simulate):
    inside, total, pooled_err = 0, 0, []
    for seed in range(3):
        trials, truth = simulate(100 + seed, n_subjects=4, n_trials=30)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ApproximationWarning)
            result = fit_psychometric(trials, rng=np.random.default_rng(seed), backend="laplace",
                                      draws=500)
        table = threshold_table(result).set_index(["subject", "standard_speed_mm_s"])
        for t in truth:
            row = table.loc[(t.subject, t.standard_speed_mm_s)]
            inside += int(row.pse_lb_um <= t.pse_um <= row.pse_ub_um)
            inside += int(row.dt_lb_um <= t.dt_um <= row.dt_ub_um)
            total += 2
        for v, pse in ((20.0, 10.0), (40.0, 10.9)):
            pooled_err.append(table.loc[("all", v)].pse_um - pse)
    assert inside / total >= 0.85, f"95 % intervals covered {inside}/{total}"
    assert np.max(np.abs(pooled_err)) < 0.5


def test_extremes_single_subject_all_correct_all_wrong_zero_rows(extreme):
    trials = extreme
    for od in (False, True):
        result = fit_psychometric(trials, rng=np.random.default_rng(0), backend="laplace",
                                  overdispersion=od, draws=300)
        table = threshold_table(result, observed=trials)
        assert list(table.subject) == ["A", "A", "all", "all"]
        numbers = table[["pse_um", "pse_lb_um", "pse_ub_um", "dt_um", "dt_lb_um", "dt_ub_um", "deviance"]]
        assert np.all(np.isfinite(numbers.to_numpy()))
        fast, slow = table.iloc[0], table.iloc[1]
        assert fast.dt_um < 1.0            # all correct: a sharp function
        assert slow.dt_um > fast.dt_um     # all wrong: the fit can only flatten


def test_untested_conditions_are_left_out_of_the_table(simulate):
    trials, _ = simulate(9, n_subjects=2)
    untested = trials.standard_speed_mm_s == 40.0
    trials.loc[untested, ["n_trials", "n_comparison_higher"]] = 0
    trials.loc[(trials.subject == "S2") & (trials.standard_speed_mm_s == 20.0),
               ["n_trials", "n_comparison_higher"]] = 0
    result = fit_psychometric(trials, rng=np.random.default_rng(0), backend="laplace", draws=200)
    table = threshold_table(result, observed=trials)
    assert list(zip(table.subject, table.standard_speed_mm_s)) == [("S1", 20.0), ("all", 20.0)]
    assert threshold_table(result).equals(table)     # only pairs with trials are fitted rows


#: how far two fits of the same likelihood, summed in another order, may differ: the mode
#: is polished to 1e-10 relative (laplace.MODE_XTOL); rounding of the sums is ~1e-13
ORDER_RTOL = 1e-8


def test_zero_trial_rows_do_not_change_the_fit(simulate):
    """A zero-trial row adds exactly 0 to the likelihood: only rounding may differ."""
    trials, _ = simulate(7, n_subjects=2)
    padded = pd.concat([trials, trials.iloc[:3].assign(n_trials=0, n_comparison_higher=0)])
    a = fit_psychometric(trials, rng=np.random.default_rng(1), backend="laplace", draws=200)
    b = fit_psychometric(padded, rng=np.random.default_rng(1), backend="laplace", draws=200)
    pd.testing.assert_frame_equal(threshold_table(a), threshold_table(b), check_exact=False,
                                  rtol=ORDER_RTOL, atol=0.0)


def test_row_order_does_not_change_the_fit(simulate):
    """The same rows shuffled (within and across subjects): only rounding may differ."""
    trials, _ = simulate(8, n_subjects=2)
    shuffled = trials.sample(frac=1.0, random_state=np.random.default_rng(5)).reset_index(drop=True)
    shuffled = shuffled.sort_values("subject", kind="stable")       # same subject order, rows mixed
    a = fit_psychometric(trials, rng=np.random.default_rng(1), backend="laplace", draws=200)
    b = fit_psychometric(shuffled, rng=np.random.default_rng(1), backend="laplace", draws=200)
    assert not shuffled.equals(trials)
    pd.testing.assert_frame_equal(threshold_table(a), threshold_table(b), check_exact=False,
                                  rtol=ORDER_RTOL, atol=0.0)


def test_newton_polish_reaches_the_exact_mode_of_a_quadratic():
    a = np.array([[4.0, 1.0], [1.0, 3.0]])
    b = np.array([1.0, -2.0])
    x, ok = newton_polish(lambda x: -0.5 * np.einsum("bi,ij,bj->b", x, a, x) + x @ b, np.array([5.0, 5.0]))
    assert ok
    np.testing.assert_allclose(x, np.linalg.solve(a, b), rtol=1e-9)


def test_outputs_and_round_trip(tmp_path, simulate):
    trials, _ = simulate(11, n_subjects=2)
    result = fit_psychometric(trials, rng=np.random.default_rng(2), backend="laplace", draws=250)
    assert result.verdict.ok and result.backend.startswith("laplace")
    out = save_psychometric(result, trials, tmp_path, force=False, note="synthetic data", plots=False)
    text = (out / "thresholds.csv").read_text()
    assert text.startswith("# synthetic data\n")
    table = pd.read_csv(out / "thresholds.csv", comment="#")
    assert tuple(table.columns) == THRESHOLD_COLUMNS and len(table) == 3 * 2
    assert np.all(table.pse_lb_um < table.pse_um) and np.all(table.dt_um < table.dt_ub_um)
    again = threshold_table(load(out))
    pd.testing.assert_frame_equal(again, table, check_exact=False, rtol=1e-5)
    with pytest.raises(OverwriteError):
        save_psychometric(result, trials, tmp_path, force=False, plots=False)


@pytest.mark.parametrize("kwargs, name", [(dict(backend="emcee"), "backend"),
                                          (dict(chains=0), "chains"), (dict(draws=2.5), "draws"),
                                          (dict(tune=-1), "tune"),
                                          (dict(target_accept=1.0), "target_accept")])
def test_bad_arguments(simulate, kwargs, name):
    trials, _ = simulate(0, n_subjects=1)
    with pytest.raises(ArgumentError, match=name):
        fit_psychometric(trials, rng=np.random.default_rng(0), **kwargs)


def test_reserved_subject_label_empty_table_and_bad_priors(simulate):
    trials, _ = simulate(0, n_subjects=1)
    with pytest.raises(ArgumentError, match="reserved"):
        make_cells(trials.assign(subject="all"))
    with pytest.raises(ArgumentError, match="empty"):
        make_cells(trials.iloc[:0])
    with pytest.raises(ArgumentError, match="pse_sd_um"):
        Priors(pse_sd_um=0.0)
