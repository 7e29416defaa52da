"""M4 with PyMC NUTS (small draws; two compiled models per module)."""
import warnings

import numpy as np
import pytest

from feeler.calib.fit import DiagnosticWarning
from feeler.calib.psychometric.fit import fit_psychometric, threshold_table

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
    assert pooled.loc[20.0].pse_lb_um <= 10.0 <= pooled.loc[20.0].pse_ub_um
    assert pooled.loc[40.0].pse_lb_um <= 10.9 <= pooled.loc[40.0].pse_ub_um
    # published direction (DESIGN §8): PSE and DT larger at 40 than at 20 mm/s
    assert pooled.loc[40.0].pse_um > pooled.loc[20.0].pse_um
    assert pooled.loc[40.0].dt_um > pooled.loc[20.0].dt_um
    assert int(result.posterior["sample_stats"]["diverging"].sum()) <= 5


def test_extremes_with_overdispersion_single_subject(extreme):
    """All-correct and all-wrong conditions, one subject, zero-trial rows: finite output."""
    result = _fit(extreme, overdispersion=True)
    table = threshold_table(result, observed=extreme)
    assert list(table.subject) == ["A", "A", "all", "all"]
    assert np.all(np.isfinite(table.drop(columns="subject").to_numpy()))
    assert np.all(np.isfinite(result.summary["mean"]))
    assert "phi" in result.priors and table.iloc[0].dt_um < table.iloc[1].dt_um


def test_separate_mode_pooled_observer_agrees_with_laplace(simulate):
    trials, _ = simulate(8, n_subjects=2, n_trials=40)
    nuts = threshold_table(_fit(trials, hierarchical=False)).set_index(["subject", "standard_speed_mm_s"])
    lap = threshold_table(fit_psychometric(trials, rng=np.random.default_rng(0), backend="laplace",
                                           draws=500)).set_index(["subject", "standard_speed_mm_s"])
    assert np.allclose(nuts.pse_um, lap.pse_um, atol=0.2)
    assert np.allclose(nuts.dt_um, lap.dt_um, rtol=0.2)
