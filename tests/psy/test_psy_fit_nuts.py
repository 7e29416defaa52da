"""M4 with PyMC NUTS (small draws; two compiled models per module)."""
import warnings

import numpy as np
import pytest

from feeler.calib.fit import DiagnosticWarning
from feeler.calib.psychometric.fit import fit_psychometric, threshold_table
from feeler.errors import ArgumentError

pytest.importorskip("pymc")


def _fit(trials, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DiagnosticWarning)   # short chains: ESS < 400 expected
        return fit_psychometric(trials, rng=np.random.default_rng(5), backend="nuts", chains=2,
                                draws=250, tune=300, **kwargs)


def test_hierarchical_recovers_subjects_and_population(simulate):
    trials, truth = simulate(21, n_subjects=5, n_trials=30)
    result = _fit(trials)
    assert "hierarchical" in result.backend
    table = threshold_table(result, observed=trials).set_index(["subject", "standard_speed_mm_s"])
    inside = 0
    for t in truth:
        row = table.loc[(t.subject, t.standard_speed_mm_s)]
        inside += int(row.pse_lb_um <= t.pse_um <= row.pse_ub_um)
        inside += int(row.dt_lb_um <= t.dt_um <= row.dt_ub_um)
    assert inside >= 0.8 * 2 * len(truth)
    pooled = table.loc["all"]
    assert set(pooled.estimand) == {"population mean"} and pooled.gof_p.isna().all()
    assert pooled.loc[20.0].pse_lb_um <= 10.0 <= pooled.loc[20.0].pse_ub_um
    assert pooled.loc[40.0].pse_lb_um <= 10.9 <= pooled.loc[40.0].pse_ub_um
    # published direction (DESIGN §8): PSE and DT larger at 40 than at 20 mm/s
    assert pooled.loc[40.0].pse_um > pooled.loc[20.0].pse_um
    assert pooled.loc[40.0].dt_um > pooled.loc[20.0].dt_um
    assert int(result.posterior["sample_stats"]["diverging"].sum()) <= 5


def test_extremes_with_overdispersion_single_subject(extreme):
    """All-correct and all-wrong conditions, one subject, zero-trial rows: finite output;
    'all' is that subject; the all-wrong condition fails the verdict."""
    result = _fit(extreme, overdispersion=True, hierarchical=False)
    table = threshold_table(result, observed=extreme)
    assert list(table.subject) == ["A", "A", "all", "all"]
    numbers = table[["pse_um", "pse_lb_um", "pse_ub_um", "dt_um", "dt_lb_um", "dt_ub_um", "deviance"]]
    assert np.all(np.isfinite(numbers.to_numpy())) and np.all(np.isfinite(result.summary["mean"]))
    assert "phi" in result.priors and table.iloc[0].dt_um < table.iloc[1].dt_um
    np.testing.assert_array_equal(table.iloc[0].pse_um, table.iloc[2].pse_um)
    assert not result.verdict.ok and any("40/20 mm/s" in p for p in result.verdict.problems)


def test_hierarchical_refuses_one_subject_and_can_report_pooled_trials(simulate, extreme):
    with pytest.raises(ArgumentError, match="at least 2 subjects"):
        _fit(extreme)
    trials, _ = simulate(22, n_subjects=3, n_trials=30)
    table = threshold_table(_fit(trials, all_estimand="pooled"))
    pooled = table[table.subject == "all"]
    assert set(pooled.estimand) == {"pooled trials"} and pooled.gof_p.notna().all()
    assert np.isnan(table.pse_map_um).all()          # no MAP of a hierarchical density


def test_separate_mode_pooled_observer_agrees_with_exact(simulate):
    trials, _ = simulate(8, n_subjects=2, n_trials=40)
    nuts = threshold_table(_fit(trials, hierarchical=False)).set_index(["subject", "standard_speed_mm_s"])
    exact = threshold_table(fit_psychometric(trials, rng=np.random.default_rng(0), draws=500))
    exact = exact.set_index(["subject", "standard_speed_mm_s"])
    assert np.allclose(nuts.pse_um, exact.pse_um, atol=0.2)
    assert np.allclose(nuts.dt_um, exact.dt_um, rtol=0.2)
    np.testing.assert_allclose(nuts.pse_map_um, exact.pse_map_um, rtol=1e-6)   # the same mode
